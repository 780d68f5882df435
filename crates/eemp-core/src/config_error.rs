//! The one error type for configuration values: names the value and the allowed range.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ConfigError {
    #[error("{name} = {value} is out of range: allowed {range}")]
    OutOfRange {
        name: String,
        value: f64,
        range: String,
    },
    #[error("{name} is not a finite number (got {value})")]
    NotFinite { name: String, value: f64 },
    #[error("{name}: {message}")]
    Invalid { name: String, message: String },
    #[error("cannot read {path}: {message}")]
    Io { path: PathBuf, message: String },
    #[error("cannot parse {path}: {message}")]
    Parse { path: PathBuf, message: String },
}

/// Checks `min <= value <= max` (and finiteness) for a named value.
/// A floor's (or a patch's) friction coefficient: finite and in (0, 2].
pub fn check_friction(name: &str, value: f64) -> Result<(), ConfigError> {
    if !value.is_finite() {
        return Err(ConfigError::NotFinite {
            name: name.to_string(),
            value,
        });
    }
    if value <= 0.0 || value > 2.0 {
        return Err(ConfigError::OutOfRange {
            name: name.to_string(),
            value,
            range: "(0, 2]".into(),
        });
    }
    Ok(())
}

pub fn check_range(name: &str, value: f64, min: f64, max: f64) -> Result<(), ConfigError> {
    if !value.is_finite() {
        return Err(ConfigError::NotFinite {
            name: name.to_string(),
            value,
        });
    }
    if value < min || value > max {
        return Err(ConfigError::OutOfRange {
            name: name.to_string(),
            value,
            range: format!("[{min}, {max}]"),
        });
    }
    Ok(())
}

/// Checks `value > 0` (and finiteness) for a named value.
pub fn check_positive(name: &str, value: f64) -> Result<(), ConfigError> {
    if !value.is_finite() {
        return Err(ConfigError::NotFinite {
            name: name.to_string(),
            value,
        });
    }
    if value <= 0.0 {
        return Err(ConfigError::OutOfRange {
            name: name.to_string(),
            value,
            range: "(0, inf)".to_string(),
        });
    }
    Ok(())
}

/// Reads and parses a TOML file into `T`, with errors that name the file.
pub fn load_toml<T: serde::de::DeserializeOwned>(path: &std::path::Path) -> Result<T, ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|e| ConfigError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    toml::from_str(&text).map_err(|e| ConfigError::Parse {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}
