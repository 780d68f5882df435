//! Raw dog motion capture (`dog_*_joint_pos.txt`, Peng et al. 2020 / AI4Animation): one frame per
//! line, 27 markers × 3 coordinates, comma separated, y up, 60 Hz.

use nalgebra::Vector3;
use std::path::{Path, PathBuf};

pub const MARKERS: usize = 27;
/// Frame period of the capture, s.
pub const MOCAP_FRAME_S: f64 = 1.0 / 60.0;

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MocapError {
    #[error("cannot read {path}: {message}")]
    Io { path: PathBuf, message: String },
    #[error("{path}: frame {frame} (line {line}) has {got} values: a frame is {MARKERS} markers × 3 = 81")]
    Width {
        path: PathBuf,
        frame: usize,
        line: usize,
        got: usize,
    },
    #[error(
        "{path}: frame {frame} (line {line}), marker {marker}: '{text}' is not a finite number"
    )]
    Value {
        path: PathBuf,
        frame: usize,
        line: usize,
        marker: usize,
        text: String,
    },
    #[error("{path} holds no frames")]
    Empty { path: PathBuf },
    #[error("{path}: frame range {start}..{end} is empty or outside the clip's {frames} frames")]
    Range {
        path: PathBuf,
        start: usize,
        end: usize,
        frames: usize,
    },
}

/// A clip: marker positions per frame in the capture's own frame (y up), m.
#[derive(Clone, Debug)]
pub struct MocapClip {
    pub path: PathBuf,
    pub frames: Vec<[Vector3<f64>; MARKERS]>,
}

impl MocapClip {
    pub fn load(path: &Path) -> Result<Self, MocapError> {
        let text = std::fs::read_to_string(path).map_err(|e| MocapError::Io {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        Self::parse(path, &text)
    }

    pub fn parse(path: &Path, text: &str) -> Result<Self, MocapError> {
        let mut frames = Vec::new();
        for (l, line) in text.lines().enumerate() {
            if line.trim().is_empty() {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let frame = frames.len();
            if fields.len() != 3 * MARKERS {
                return Err(MocapError::Width {
                    path: path.to_path_buf(),
                    frame,
                    line: l + 1,
                    got: fields.len(),
                });
            }
            let mut markers = [Vector3::zeros(); MARKERS];
            for (i, f) in fields.iter().enumerate() {
                let v: f64 = f
                    .parse()
                    .ok()
                    .filter(|v: &f64| v.is_finite())
                    .ok_or_else(|| MocapError::Value {
                        path: path.to_path_buf(),
                        frame,
                        line: l + 1,
                        marker: i / 3,
                        text: f.to_string(),
                    })?;
                markers[i / 3][i % 3] = v;
            }
            frames.push(markers);
        }
        if frames.is_empty() {
            return Err(MocapError::Empty {
                path: path.to_path_buf(),
            });
        }
        Ok(MocapClip {
            path: path.to_path_buf(),
            frames,
        })
    }

    /// Frames `start..end` (half-open, as the original work's `frames[start:end]`).
    pub fn window(
        &self,
        start: usize,
        end: usize,
    ) -> Result<&[[Vector3<f64>; MARKERS]], MocapError> {
        if start >= end || end > self.frames.len() {
            return Err(MocapError::Range {
                path: self.path.clone(),
                start,
                end,
                frames: self.frames.len(),
            });
        }
        Ok(&self.frames[start..end])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(v: f64) -> String {
        vec![format!("{v:.5}"); 81].join(",\t")
    }

    #[test]
    fn parses_frames_and_names_bad_ones() {
        let p = Path::new("clip.txt");
        let ok = format!("{}\n{}\n", line(0.1), line(0.2));
        let c = MocapClip::parse(p, &ok).unwrap();
        assert_eq!(c.frames.len(), 2);
        assert_eq!(c.frames[1][26], Vector3::new(0.2, 0.2, 0.2));

        let short = format!("{}\n0.1, 0.2\n", line(0.1));
        let e = MocapClip::parse(p, &short).unwrap_err();
        assert!(
            matches!(
                e,
                MocapError::Width {
                    frame: 1,
                    got: 2,
                    ..
                }
            ),
            "{e}"
        );

        let mut bad: Vec<String> = vec!["0.1".into(); 81];
        bad[7] = "nan".into();
        let e = MocapClip::parse(p, &bad.join(",")).unwrap_err();
        assert!(
            matches!(
                e,
                MocapError::Value {
                    frame: 0,
                    marker: 2,
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("marker 2"));

        assert!(matches!(
            MocapClip::parse(p, "\n\n").unwrap_err(),
            MocapError::Empty { .. }
        ));
        assert!(matches!(
            c.window(1, 1).unwrap_err(),
            MocapError::Range { .. }
        ));
        assert!(c.window(0, 3).is_err());
        assert_eq!(c.window(0, 2).unwrap().len(), 2);
    }
}
