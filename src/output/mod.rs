//! Outputs: time series CSV, JSON summary, plots. Every file is written to a temporary
//! name in the same directory and renamed into place, so a reader never sees half a file.

mod plot;
pub use plot::*;

use crate::error::{Error, Result};
use crate::sim::Record;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Write `bytes` to `path` atomically (temp file in the same directory, then rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let werr = |e: std::io::Error| Error::Write { path: path.to_path_buf(), message: e.to_string() };
    let tmp = tmp_path(path);
    let res = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if res.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    res.map_err(werr)
}

/// The temporary name used while writing `path`.
pub fn tmp_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().map(|n| n.to_os_string()).unwrap_or_default();
    name.push(".tmp");
    path.with_file_name(name)
}

/// The time series as CSV text. Header row = column names with units in their suffixes.
/// Floats use Rust's shortest round-trip formatting, so equal runs give equal bytes.
pub fn timeseries_csv(columns: &[(&str, &[f64])]) -> Result<Vec<u8>> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let cerr = |e: csv::Error| Error::Write { path: PathBuf::from("timeseries.csv"), message: e.to_string() };
    w.write_record(columns.iter().map(|(n, _)| *n)).map_err(cerr)?;
    let rows = columns.first().map_or(0, |c| c.1.len());
    let mut buf = ryu_like::Buf::default();
    for i in 0..rows {
        w.write_record(columns.iter().map(|(_, c)| buf.fmt(c[i]))).map_err(cerr)?;
    }
    w.into_inner().map_err(|e| Error::Write { path: PathBuf::from("timeseries.csv"), message: e.to_string() })
}

mod ryu_like {
    /// Formats an f64 with Rust's shortest round-trip `Display`.
    #[derive(Default)]
    pub struct Buf(String);
    impl Buf {
        pub fn fmt(&mut self, x: f64) -> String {
            use std::fmt::Write;
            self.0.clear();
            let _ = write!(self.0, "{x}");
            self.0.clone()
        }
    }
}

/// Write `timeseries.csv`, `summary.json` and `force_tracking.png` for a run into `dir`.
pub fn write_run(dir: &Path, record: &Record, summary_json: &serde_json::Value, title: &str) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::Write { path: dir.to_path_buf(), message: e.to_string() })?;
    write_atomic(&dir.join("timeseries.csv"), &timeseries_csv(&record.columns())?)?;
    let json = serde_json::to_vec_pretty(summary_json)
        .map_err(|e| Error::Write { path: dir.join("summary.json"), message: e.to_string() })?;
    write_atomic(&dir.join("summary.json"), &json)?;
    force_tracking_png(&dir.join("force_tracking.png"), record, title)?;
    if !record.ref_knee_deg.is_empty() {
        knee_tracking_png(&dir.join("knee_tracking.png"), record, title)?;
    }
    Ok(())
}
