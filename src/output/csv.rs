//! `timeseries.csv`, streamed as the run goes: the rows' values go in chunks to a writer
//! thread that formats them, writes them through a buffer and syncs the file every 512 KiB.
//!
//! Floats are written in their shortest round-trip form (the shortest digits that read back to
//! the same bits, in positional or exponent notation as `ryu` chooses: `0.25`, `1e-7`,
//! `2.5e16`) straight into the line buffer, with no allocation per field: equal runs give
//! equal bytes, and every value parses back bit for bit (tested). Non-finite values are `NaN`,
//! `inf`, `-inf`; an integral value keeps its `.0`. It replaced Rust's `Display` (issue 24:
//! about 900 instructions per value, most of the run on the fast paths); the two differ in
//! notation and, for ties between two shortest candidates, in the last digit, never in the
//! value read back. The digits come from `zmij` (issue 41: 16 ns a value against ryu's 36 on
//! this machine), which writes ryu's bytes but for the `+` of a positive exponent, dropped
//! here (the same bytes as ryu on 20 million values, tested against ryu below).

use crate::error::{Error, Result};
use crate::record::{Layout, RecordSink, Row};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Append `x` to `out` in its shortest round-trip form (`1.0`, `1e-7`, `-0.0`, `NaN`, `inf`).
pub fn push_f64(out: &mut Vec<u8>, x: f64) {
    if x == 0.0 {
        // A tenth of a row's values or more are zeros (the idle columns).
        out.extend_from_slice(if x.is_sign_negative() { b"-0.0" } else { b"0.0" });
    } else if x.is_finite() {
        let mut b = zmij::Buffer::new();
        let s = b.format_finite(x).as_bytes();
        // zmij writes a positive exponent with its sign (`1e+16`), ryu without (`1e16`).
        match s.iter().position(|&c| c == b'+') {
            Some(p) => {
                out.extend_from_slice(&s[..p]);
                out.extend_from_slice(&s[p + 1..]);
            }
            None => out.extend_from_slice(s),
        }
    } else if x.is_nan() {
        out.extend_from_slice(b"NaN");
    } else if x > 0.0 {
        out.extend_from_slice(b"inf");
    } else {
        out.extend_from_slice(b"-inf");
    }
}

/// Rows handed to the writer thread at a time: small, because the last chunk is formatted
/// after the simulation ends (2048 rows left a fifth of a 10,000-row run's formatting there:
/// the reduced engine's CSV run took 1.27-1.33x its in-memory run instead of 1.21-1.28x).
const CHUNK_ROWS: usize = 256;
/// Chunks in flight between the run and the writer thread (bounds the memory).
const CHUNKS_IN_FLIGHT: usize = 32;
/// The writer thread syncs the file to disk after about this many bytes (so the final sync at
/// [`CsvSink::finish`] has little left to write: measured with 2048-row chunks on the reduced
/// engine's 2.5 MB run on a loaded machine, 1.7x the in-memory run's time against 2.0x syncing
/// every 8 MiB and 2.5x writing in line).
const SYNC_EVERY_BYTES: usize = 1 << 19;

/// Streams rows to a CSV file: the run hands the rows' values in chunks to a writer thread,
/// which formats them, writes them through a buffer and syncs the file as it goes, so the
/// formatting and the disk overlap the simulation. The bytes are the same as formatting in
/// line (the thread is only a pipeline).
pub struct CsvSink {
    path: PathBuf,
    /// The file until `start` hands it to the writer thread.
    file: Option<std::fs::File>,
    layout: Layout,
    chunk: Vec<f64>,
    tx: Option<std::sync::mpsc::SyncSender<Vec<f64>>>,
    writer: Option<std::thread::JoinHandle<std::io::Result<()>>>,
}

impl CsvSink {
    /// Create (truncate) the file at `path`.
    pub fn create(path: &Path) -> Result<Self> {
        let f = std::fs::File::create(path)
            .map_err(|e| Error::Write { path: path.to_path_buf(), message: e.to_string() })?;
        Ok(Self {
            path: path.to_path_buf(),
            file: Some(f),
            layout: Layout::default(),
            chunk: Vec::new(),
            tx: None,
            writer: None,
        })
    }

    fn werr(&self, e: std::io::Error) -> Error {
        Error::Write { path: self.path.clone(), message: e.to_string() }
    }

    /// Hand the current chunk to the writer thread; a thread that stopped on an error reports
    /// it here.
    fn send(&mut self) -> Result<()> {
        if self.chunk.is_empty() {
            return Ok(());
        }
        let width = self.layout.width().max(1);
        let full = std::mem::replace(&mut self.chunk, Vec::with_capacity(CHUNK_ROWS * width));
        match self.tx.as_ref().map(|tx| tx.send(full)) {
            Some(Ok(())) => Ok(()),
            _ => Err(self.join().err().unwrap_or_else(|| self.werr(std::io::Error::other("the CSV writer stopped")))),
        }
    }

    /// Close the channel and wait for the writer thread: its I/O error, if it had one.
    fn join(&mut self) -> Result<()> {
        self.tx = None;
        match self.writer.take().map(|h| h.join()) {
            None | Some(Ok(Ok(()))) => Ok(()),
            Some(Ok(Err(e))) => Err(self.werr(e)),
            Some(Err(_)) => Err(self.werr(std::io::Error::other("the CSV writer thread panicked"))),
        }
    }

    /// Write what is left, flush and sync the file.
    pub fn finish(mut self) -> Result<()> {
        self.send()?;
        self.join()?;
        match self.file.take() {
            // `start` was never called: nothing but an empty file.
            Some(f) => f.sync_all().map_err(|e| self.werr(e)),
            None => Ok(()),
        }
    }
}

impl Drop for CsvSink {
    /// A sink dropped without `finish` (a run that failed) still waits for its thread.
    fn drop(&mut self) {
        let _ = self.join();
    }
}

/// The writer thread: format each chunk of `width`-value rows, write, sync every
/// [`SYNC_EVERY_BYTES`], and flush and sync at the end.
fn write_rows(
    mut w: std::io::BufWriter<std::fs::File>,
    rx: std::sync::mpsc::Receiver<Vec<f64>>,
    width: usize,
) -> std::io::Result<()> {
    let mut line = Vec::with_capacity(1 << 16);
    let mut since_sync = 0usize;
    for chunk in rx {
        for row in chunk.chunks(width) {
            for (i, v) in row.iter().enumerate() {
                if i > 0 {
                    line.push(b',');
                }
                push_f64(&mut line, *v);
            }
            line.push(b'\n');
        }
        w.write_all(&line)?;
        since_sync += line.len();
        line.clear();
        if since_sync >= SYNC_EVERY_BYTES {
            w.flush()?;
            w.get_ref().sync_data()?;
            since_sync = 0;
        }
    }
    w.flush()?;
    w.get_ref().sync_all()
}

impl RecordSink for CsvSink {
    fn start(&mut self, layout: &Layout) -> Result<()> {
        self.layout = layout.clone();
        let Some(file) = self.file.take() else { return Ok(()) };
        let mut w = std::io::BufWriter::with_capacity(1 << 16, file);
        let header = layout.names().join(",") + "\n";
        w.write_all(header.as_bytes()).map_err(|e| self.werr(e))?;
        let width = layout.width().max(1);
        let (tx, rx) = std::sync::mpsc::sync_channel(CHUNKS_IN_FLIGHT);
        let writer = std::thread::Builder::new()
            .name("exoleg-csv".into())
            .spawn(move || write_rows(w, rx, width))
            .map_err(|e| self.werr(e))?;
        (self.tx, self.writer, self.chunk) = (Some(tx), Some(writer), Vec::with_capacity(CHUNK_ROWS * width));
        Ok(())
    }

    fn row(&mut self, row: &Row) -> Result<()> {
        let before = self.chunk.len();
        row.values_into(&self.layout, &mut self.chunk);
        debug_assert_eq!(self.chunk.len() - before, self.layout.width());
        if self.chunk.len() >= CHUNK_ROWS * self.layout.width().max(1) {
            self.send()?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::push_f64;

    /// The bytes are ryu's (what the files held before zmij), on special values and two
    /// million pseudo-random values of every magnitude.
    #[test]
    fn bytes_are_ryus() {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut line = Vec::new();
        for v in [0.0, -0.0] {
            line.clear();
            push_f64(&mut line, v);
            assert_eq!(line, ryu::Buffer::new().format_finite(v).as_bytes());
        }
        for i in 0..2_000_000u64 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let v = match i % 3 {
                0 => f64::from_bits(x),
                1 => (x as f64 / u64::MAX as f64 - 0.5) * 10f64.powi((x % 40) as i32 - 20),
                _ => (x % 100_000) as f64 * 0.5,
            };
            if !v.is_finite() {
                continue;
            }
            line.clear();
            push_f64(&mut line, v);
            let mut r = ryu::Buffer::new();
            assert_eq!(line, r.format_finite(v).as_bytes(), "{v:e}");
        }
    }

    /// Every value written parses back to the same bits: special values, subnormals, the
    /// extremes, and a million pseudo-random bit patterns (xorshift, fixed seed).
    #[test]
    fn values_parse_back_bit_for_bit() {
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let specials = [0.0, -0.0, 1.0, 0.1, 1e-7, 2.5e16, f64::MIN_POSITIVE, 5e-324, f64::MAX, -f64::MAX, 123456.0];
        let randoms = (0..1_000_000).map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            f64::from_bits(x)
        });
        let mut line = Vec::new();
        for v in specials.into_iter().chain(randoms) {
            line.clear();
            push_f64(&mut line, v);
            let back: f64 = std::str::from_utf8(&line).unwrap().parse().unwrap();
            if v.is_nan() {
                assert!(back.is_nan());
            } else {
                assert_eq!(back.to_bits(), v.to_bits(), "{v:e} written as {}", String::from_utf8_lossy(&line));
            }
        }
        for (v, s) in [
            (f64::INFINITY, "inf"),
            (f64::NEG_INFINITY, "-inf"),
            (f64::NAN, "NaN"),
            (1e-7, "1e-7"),
            (2.0, "2.0"),
            (0.0, "0.0"),
            (-0.0, "-0.0"),
        ] {
            line.clear();
            push_f64(&mut line, v);
            assert_eq!(line, s.as_bytes());
        }
    }
}
