//! `timeseries.csv`, streamed row by row through a buffer as the run goes.
//!
//! Floats are written with Rust's `Display` (shortest round-trip digits, plain positional
//! notation) straight into the line buffer, with no allocation per field: equal runs give
//! equal bytes, and the file reads back bit for bit. (`ryu` was tried: it rounds ties between
//! two shortest candidates to even, `Display` rounds them away from zero, so `ryu` would change
//! a few values in a million in their last digit and break byte-identity with earlier outputs.)

use crate::error::{Error, Result};
use crate::record::{Layout, RecordSink, Row};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Append `x` to `out` as `Display` prints it (`1`, `0.0000001`, `-0`, `NaN`, `inf`).
pub fn push_f64(out: &mut Vec<u8>, x: f64) {
    // Writing into a Vec cannot fail.
    let _ = write!(out, "{x}");
}

/// Streams rows to a CSV file through a buffer.
pub struct CsvSink {
    path: PathBuf,
    w: std::io::BufWriter<std::fs::File>,
    layout: Layout,
    line: Vec<u8>,
    values: Vec<f64>,
}

impl CsvSink {
    /// Create (truncate) the file at `path`.
    pub fn create(path: &Path) -> Result<Self> {
        let f = std::fs::File::create(path)
            .map_err(|e| Error::Write { path: path.to_path_buf(), message: e.to_string() })?;
        Ok(Self {
            path: path.to_path_buf(),
            w: std::io::BufWriter::with_capacity(1 << 16, f),
            layout: Layout::default(),
            line: Vec::with_capacity(1024),
            values: Vec::with_capacity(40),
        })
    }

    fn werr(&self, e: std::io::Error) -> Error {
        Error::Write { path: self.path.clone(), message: e.to_string() }
    }

    /// Flush and sync the file.
    pub fn finish(mut self) -> Result<()> {
        self.w.flush().map_err(|e| self.werr(e))?;
        self.w.get_ref().sync_all().map_err(|e| self.werr(e))
    }
}

impl RecordSink for CsvSink {
    fn start(&mut self, layout: &Layout) -> Result<()> {
        self.layout = layout.clone();
        let header = layout.names().join(",") + "\n";
        self.w.write_all(header.as_bytes()).map_err(|e| self.werr(e))
    }

    fn row(&mut self, row: &Row) -> Result<()> {
        self.values.clear();
        row.values_into(&self.layout, &mut self.values);
        self.line.clear();
        for (i, v) in self.values.iter().enumerate() {
            if i > 0 {
                self.line.push(b',');
            }
            push_f64(&mut self.line, *v);
        }
        self.line.push(b'\n');
        self.w.write_all(&self.line).map_err(|e| self.werr(e))
    }
}
