//! `timeseries.parquet` (`output.format = "parquet"`): the columns of `timeseries.csv` as
//! required doubles, SNAPPY-compressed, streamed in row groups of [`ROW_GROUP_ROWS`] rows
//! (the arrow-rs `parquet` crate's column writers; pandas, polars and pyarrow read it). The
//! values are the f64s themselves: nothing is rounded or formatted.

use crate::error::{Error, Result};
use crate::record::{Layout, RecordSink, Row};
use parquet::basic::{Compression, Repetition, Type as PhysicalType};
use parquet::data_type::DoubleType;
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::Type;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Rows per row group (a group is held in memory until written: 64 Ki rows x 8 bytes per
/// column).
pub const ROW_GROUP_ROWS: usize = 65_536;

/// Streams rows to a Parquet file.
pub struct ParquetSink {
    path: PathBuf,
    file: Option<std::fs::File>,
    writer: Option<SerializedFileWriter<std::fs::File>>,
    layout: Layout,
    columns: Vec<Vec<f64>>,
    values: Vec<f64>,
}

impl ParquetSink {
    /// Create (truncate) the file at `path`.
    pub fn create(path: &Path) -> Result<Self> {
        let file = std::fs::File::create(path)
            .map_err(|e| Error::Write { path: path.to_path_buf(), message: e.to_string() })?;
        Ok(Self {
            path: path.to_path_buf(),
            file: Some(file),
            writer: None,
            layout: Layout::default(),
            columns: Vec::new(),
            values: Vec::with_capacity(64),
        })
    }

    fn werr(&self, e: impl std::fmt::Display) -> Error {
        Error::Write { path: self.path.clone(), message: e.to_string() }
    }

    /// Write the rows held as one row group.
    fn flush_group(&mut self) -> Result<()> {
        if self.columns.first().is_none_or(|c| c.is_empty()) {
            return Ok(());
        }
        let Some(w) = self.writer.as_mut() else { return Ok(()) };
        let mut group =
            w.next_row_group().map_err(|e| Error::Write { path: self.path.clone(), message: e.to_string() })?;
        let mut i = 0;
        while let Some(mut col) =
            group.next_column().map_err(|e| Error::Write { path: self.path.clone(), message: e.to_string() })?
        {
            let values = &self.columns[i];
            col.typed::<DoubleType>()
                .write_batch(values, None, None)
                .and_then(|_| col.close())
                .map_err(|e| Error::Write { path: self.path.clone(), message: e.to_string() })?;
            i += 1;
        }
        group.close().map_err(|e| self.werr(e))?;
        for c in &mut self.columns {
            c.clear();
        }
        Ok(())
    }

    /// Write the last row group and the footer, and sync the file.
    pub fn finish(mut self) -> Result<()> {
        self.flush_group()?;
        let Some(w) = self.writer.take() else { return Ok(()) };
        let file = w.into_inner().map_err(|e| self.werr(e))?;
        file.sync_all().map_err(|e| self.werr(e))
    }
}

impl RecordSink for ParquetSink {
    fn start(&mut self, layout: &Layout) -> Result<()> {
        self.layout = layout.clone();
        let names = layout.names();
        let fields = names
            .iter()
            .map(|n| {
                Type::primitive_type_builder(n, PhysicalType::DOUBLE)
                    .with_repetition(Repetition::REQUIRED)
                    .build()
                    .map(Arc::new)
            })
            .collect::<std::result::Result<Vec<_>, _>>()
            .map_err(|e| self.werr(e))?;
        let schema = Type::group_type_builder("timeseries").with_fields(fields).build().map_err(|e| self.werr(e))?;
        let props = WriterProperties::builder()
            .set_compression(Compression::SNAPPY)
            .set_created_by(format!("exoleg {}", env!("CARGO_PKG_VERSION")))
            .build();
        let file = self.file.take().ok_or_else(|| self.werr("started twice"))?;
        self.writer =
            Some(SerializedFileWriter::new(file, Arc::new(schema), Arc::new(props)).map_err(|e| self.werr(e))?);
        self.columns = vec![Vec::with_capacity(ROW_GROUP_ROWS.min(4096)); names.len()];
        Ok(())
    }

    fn row(&mut self, row: &Row) -> Result<()> {
        self.values.clear();
        row.values_into(&self.layout, &mut self.values);
        for (c, v) in self.columns.iter_mut().zip(&self.values) {
            c.push(*v);
        }
        if self.columns.first().is_some_and(|c| c.len() >= ROW_GROUP_ROWS) {
            self.flush_group()?;
        }
        Ok(())
    }
}

/// The time-series file of a run: `timeseries.csv` or `timeseries.parquet`
/// (`output.format`).
pub enum TimeSeriesSink {
    /// `timeseries.csv`.
    Csv(super::CsvSink),
    /// `timeseries.parquet`.
    Parquet(ParquetSink),
}

impl TimeSeriesSink {
    /// Create the file in `dir`: `timeseries.parquet` when `parquet`, else `timeseries.csv`.
    pub fn create(dir: &Path, parquet: bool) -> Result<Self> {
        Ok(if parquet {
            TimeSeriesSink::Parquet(ParquetSink::create(&dir.join("timeseries.parquet"))?)
        } else {
            TimeSeriesSink::Csv(super::CsvSink::create(&dir.join("timeseries.csv"))?)
        })
    }

    /// Flush and sync the file.
    pub fn finish(self) -> Result<()> {
        match self {
            TimeSeriesSink::Csv(s) => s.finish(),
            TimeSeriesSink::Parquet(s) => s.finish(),
        }
    }
}

impl RecordSink for TimeSeriesSink {
    fn start(&mut self, layout: &Layout) -> Result<()> {
        match self {
            TimeSeriesSink::Csv(s) => s.start(layout),
            TimeSeriesSink::Parquet(s) => s.start(layout),
        }
    }
    fn row(&mut self, row: &Row) -> Result<()> {
        match self {
            TimeSeriesSink::Csv(s) => s.row(row),
            TimeSeriesSink::Parquet(s) => s.row(row),
        }
    }
}
