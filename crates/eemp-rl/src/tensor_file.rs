//! Named f32 arrays with string metadata in one safetensors file, written atomically (a kill
//! mid-write leaves the previous file intact).

use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

/// The same safetensors bytes with the JSON header's keys sorted (and the metadata's inside
/// it): the crate writes its metadata map in hash order, which differs from run to run, so two
/// equal files would differ in bytes. Data offsets are relative to the data, so they stand.
fn canonical_header(bytes: Vec<u8>) -> Result<Vec<u8>, String> {
    let bad = || "safetensors serialised a malformed header".to_string();
    let n = u64::from_le_bytes(
        bytes
            .get(..8)
            .ok_or_else(bad)?
            .try_into()
            .map_err(|_| bad())?,
    ) as usize;
    let header = bytes.get(8..8 + n).ok_or_else(bad)?;
    // serde_json's map is a BTreeMap (no `preserve_order`): keys come out sorted.
    let value: serde_json::Value = serde_json::from_slice(header).map_err(|_| bad())?;
    let mut sorted = serde_json::to_vec(&value).map_err(|_| bad())?;
    // The format pads the header with spaces to a multiple of 8 bytes.
    sorted.resize(sorted.len().next_multiple_of(8), b' ');
    let mut out = Vec::with_capacity(8 + sorted.len() + bytes.len() - 8 - n);
    out.extend_from_slice(&(sorted.len() as u64).to_le_bytes());
    out.extend_from_slice(&sorted);
    out.extend_from_slice(&bytes[8 + n..]);
    Ok(out)
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct TensorFile {
    pub tensors: BTreeMap<String, (Vec<usize>, Vec<f32>)>,
    pub metadata: HashMap<String, String>,
}

impl TensorFile {
    pub fn insert(&mut self, name: &str, shape: Vec<usize>, data: Vec<f32>) {
        debug_assert_eq!(shape.iter().product::<usize>(), data.len());
        self.tensors.insert(name.to_string(), (shape, data));
    }

    pub fn insert_tensor(
        &mut self,
        name: &str,
        t: &candle_core::Tensor,
    ) -> candle_core::Result<()> {
        let shape = t.dims().to_vec();
        let data = t.flatten_all()?.to_vec1::<f32>()?;
        self.insert(name, shape, data);
        Ok(())
    }

    pub fn get(&self, file: &Path, name: &str) -> Result<&(Vec<usize>, Vec<f32>), String> {
        self.tensors
            .get(name)
            .ok_or_else(|| format!("{}: no tensor '{name}'", file.display()))
    }

    /// The tensor `name`, checked to have `shape`.
    pub fn tensor(
        &self,
        file: &Path,
        name: &str,
        shape: &[usize],
    ) -> Result<candle_core::Tensor, String> {
        let (s, d) = self.get(file, name)?;
        if s != shape {
            return Err(format!(
                "{}: tensor '{name}' has shape {s:?}, expected {shape:?}",
                file.display()
            ));
        }
        candle_core::Tensor::from_vec(d.clone(), s.clone(), &candle_core::Device::Cpu)
            .map_err(|e| e.to_string())
    }

    pub fn meta(&self, file: &Path, key: &str) -> Result<&str, String> {
        self.metadata
            .get(key)
            .map(|s| s.as_str())
            .ok_or_else(|| format!("{}: no metadata '{key}'", file.display()))
    }

    pub fn save(&self, path: &Path) -> Result<(), String> {
        let bytes: Vec<(String, Vec<usize>, Vec<u8>)> = self
            .tensors
            .iter()
            .map(|(k, (s, d))| {
                (
                    k.clone(),
                    s.clone(),
                    d.iter().flat_map(|v| v.to_le_bytes()).collect(),
                )
            })
            .collect();
        let views = bytes
            .iter()
            .map(|(k, s, b)| {
                TensorView::new(Dtype::F32, s.clone(), b)
                    .map(|v| (k.clone(), v))
                    .map_err(|e| e.to_string())
            })
            .collect::<Result<Vec<_>, _>>()?;
        let tmp = path.with_extension("tmp");
        let bytes = safetensors::serialize(views, Some(self.metadata.clone()))
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        std::fs::write(&tmp, canonical_header(bytes)?)
            .map_err(|e| format!("cannot write {}: {e}", tmp.display()))?;
        std::fs::rename(&tmp, path).map_err(|e| format!("cannot write {}: {e}", path.display()))
    }

    pub fn load(path: &Path) -> Result<Self, String> {
        let buf =
            std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        let bad = |e: safetensors::SafeTensorError| {
            format!("{} is not a valid safetensors file: {e}", path.display())
        };
        let (_, meta) = SafeTensors::read_metadata(&buf).map_err(bad)?;
        let st = SafeTensors::deserialize(&buf).map_err(bad)?;
        let mut out = TensorFile {
            metadata: meta.metadata().clone().unwrap_or_default(),
            ..Default::default()
        };
        for name in st.names() {
            let v = st.tensor(name).map_err(bad)?;
            if v.dtype() != Dtype::F32 {
                return Err(format!(
                    "{}: tensor '{name}' is {:?}, expected F32",
                    path.display(),
                    v.dtype()
                ));
            }
            let data = v
                .data()
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect();
            out.insert(name, v.shape().to_vec(), data);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_files_are_equal_bytes_whatever_the_metadata_order() {
        let dir = tempfile::tempdir().unwrap();
        let mut f = TensorFile::default();
        f.insert("b", vec![2], vec![1.0, 2.0]);
        f.insert("a", vec![1], vec![3.0]);
        for i in 0..20 {
            f.metadata.insert(format!("key{i}"), format!("value {i}"));
        }
        let mut bytes = Vec::new();
        for k in 0..4 {
            // A fresh map each time: a new hash order.
            let g = TensorFile {
                metadata: f.metadata.clone().into_iter().collect(),
                ..f.clone()
            };
            let p = dir.path().join(format!("{k}.safetensors"));
            g.save(&p).unwrap();
            bytes.push(std::fs::read(&p).unwrap());
            assert_eq!(TensorFile::load(&p).unwrap(), f, "reads back");
        }
        assert!(bytes.windows(2).all(|w| w[0] == w[1]), "same bytes");
    }
}
