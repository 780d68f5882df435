//! Writing run outputs: the output folder, summary.json, and a trace.csv streamed row by row.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("cannot create output folder {path}: {message}")]
    Folder { path: PathBuf, message: String },
    #[error("cannot write {path}: {message}")]
    Write { path: PathBuf, message: String },
}

pub fn create_dir(dir: &Path) -> Result<(), OutputError> {
    std::fs::create_dir_all(dir).map_err(|e| OutputError::Folder {
        path: dir.to_path_buf(),
        message: e.to_string(),
    })
}

pub fn write_json(path: &Path, value: &serde_json::Value) -> Result<(), OutputError> {
    let text = serde_json::to_string_pretty(value).expect("JSON value serialises");
    std::fs::write(path, text + "\n").map_err(|e| OutputError::Write {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// A CSV file written as the run goes, so a killed run keeps what it had.
pub struct Trace {
    path: PathBuf,
    writer: csv::Writer<BufWriter<File>>,
}

impl Trace {
    pub fn create(path: &Path, header: &[String]) -> Result<Self, OutputError> {
        let file = File::create(path).map_err(|e| OutputError::Write {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let mut writer = csv::Writer::from_writer(BufWriter::new(file));
        writer
            .write_record(header)
            .map_err(|e| OutputError::Write {
                path: path.to_path_buf(),
                message: e.to_string(),
            })?;
        Ok(Trace {
            path: path.to_path_buf(),
            writer,
        })
    }

    pub fn row(&mut self, values: &[f64]) -> Result<(), OutputError> {
        self.writer
            .write_record(values.iter().map(|v| format!("{v:.6}")))
            .map_err(|e| OutputError::Write {
                path: self.path.clone(),
                message: e.to_string(),
            })
    }

    pub fn finish(mut self) -> Result<(), OutputError> {
        self.writer.flush().map_err(|e| OutputError::Write {
            path: self.path.clone(),
            message: e.to_string(),
        })
    }
}
