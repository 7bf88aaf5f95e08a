//! The model file: safetensors with PyTorch-style tensor names and the
//! model's metadata as JSON strings in the header (`docs/model-format.md`).
//! Bytes in, bytes out: writing the file is the caller's business.

use std::collections::HashMap;

use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use thiserror::Error;

use super::model::{DekfModel, ModelMeta};
use super::params::{Architecture, Layout};

/// Metadata key holding the JSON of [`ModelMeta`].
pub const META_KEY: &str = "slidetrack.dekf";
/// Metadata key holding the JSON of the networks' [`Architecture`]
/// (`{"width": 64, "residual_blocks": 3, "activation": "relu"}`); a file
/// without it has the thesis's.
pub const ARCHITECTURE_KEY: &str = "slidetrack.dekf.architecture";
/// Metadata key holding the format version.
pub const FORMAT_KEY: &str = "format";
/// The format written.
pub const FORMAT: &str = "slidetrack-dekf-1";

/// A model file that cannot be read.
#[derive(Debug, Error)]
pub enum ModelFileError {
    /// Not a safetensors file, or a corrupt one.
    #[error("not a valid safetensors file: {0}")]
    Safetensors(#[from] safetensors::SafeTensorError),
    /// The header has no slidetrack metadata, or it does not parse.
    #[error("missing or invalid `{META_KEY}` metadata: {detail}")]
    Metadata {
        /// What is wrong.
        detail: String,
    },
    /// The architecture metadata does not parse or is not usable.
    #[error("invalid `{ARCHITECTURE_KEY}` metadata: {detail}")]
    Architecture {
        /// What is wrong.
        detail: String,
    },
    /// A tensor is missing or has the wrong shape or type.
    #[error("tensor `{name}`: {detail}")]
    Tensor {
        /// The tensor.
        name: String,
        /// What is wrong.
        detail: String,
    },
}

/// Row-major values of an entry (weights transposed from column-major).
fn export(model: &DekfModel, name: &str, shape: &[usize], offset: usize) -> Vec<f32> {
    let p = &model.params;
    if shape.len() == 2 && name.ends_with(".weight") {
        let (out, inp) = (shape[0], shape[1]);
        let mut v = vec![0.0f32; out * inp];
        for o in 0..out {
            for i in 0..inp {
                v[o * inp + i] = p[offset + i * out + o];
            }
        }
        v
    } else {
        let n: usize = shape.iter().product();
        p[offset..offset + n].to_vec()
    }
}

/// The model as safetensors bytes.
pub fn to_bytes(model: &DekfModel) -> Result<Vec<u8>, ModelFileError> {
    let values: Vec<(String, Vec<usize>, Vec<u8>)> = model
        .layout
        .entries
        .iter()
        .map(|e| {
            let v = export(model, &e.name, &e.shape, e.offset);
            (e.name.clone(), e.shape.clone(), v.iter().flat_map(|x| x.to_le_bytes()).collect())
        })
        .collect();
    let views = values
        .iter()
        .map(|(name, shape, bytes)| Ok((name.as_str(), TensorView::new(Dtype::F32, shape.clone(), bytes)?)))
        .collect::<Result<Vec<_>, safetensors::SafeTensorError>>()?;
    let meta =
        serde_json::to_string(&model.meta).map_err(|e| ModelFileError::Metadata { detail: e.to_string() })?;
    let arch = serde_json::to_string(model.architecture())
        .map_err(|e| ModelFileError::Metadata { detail: e.to_string() })?;
    let info = HashMap::from([
        (META_KEY.to_string(), meta),
        (ARCHITECTURE_KEY.to_string(), arch),
        (FORMAT_KEY.to_string(), FORMAT.to_string()),
    ]);
    Ok(with_sorted_header(safetensors::serialize(views, Some(info))?))
}

/// `bytes` with the keys of its safetensors header in sorted order (the
/// dEKF's model files and the linear map's alike).
/// safetensors writes the metadata from a `HashMap`, whose order changes
/// from process to process; sorted, the same model gives the same bytes.
/// The header keeps its length (padded with spaces, as the format allows).
pub(crate) fn with_sorted_header(bytes: Vec<u8>) -> Vec<u8> {
    fn sorted(v: serde_json::Value) -> serde_json::Value {
        match v {
            serde_json::Value::Object(m) => {
                let mut entries: Vec<_> = m.into_iter().collect();
                entries.sort_by(|a, b| a.0.cmp(&b.0));
                serde_json::Value::Object(entries.into_iter().map(|(k, v)| (k, sorted(v))).collect())
            }
            other => other,
        }
    }
    let Some(n) = bytes.get(..8).and_then(|b| b.try_into().ok()).map(u64::from_le_bytes) else {
        return bytes;
    };
    let Some(header) = usize::try_from(n).ok().and_then(|n| bytes.get(8..8 + n)) else {
        return bytes;
    };
    let Ok(value) = serde_json::from_slice::<serde_json::Value>(header) else {
        return bytes;
    };
    let Ok(mut json) = serde_json::to_vec(&sorted(value)) else {
        return bytes;
    };
    if json.len() > header.len() {
        return bytes;
    }
    json.resize(header.len(), b' ');
    let mut out = bytes;
    out[8..8 + json.len()].copy_from_slice(&json);
    out
}

/// A model from safetensors bytes written by [`to_bytes`] (or by any tool that
/// follows `docs/model-format.md`).
pub fn from_bytes(bytes: &[u8]) -> Result<DekfModel, ModelFileError> {
    let st = SafeTensors::deserialize(bytes)?;
    let (_, header) = SafeTensors::read_metadata(bytes)?;
    let metadata = header.metadata().as_ref();
    let meta_json = metadata
        .and_then(|m| m.get(META_KEY))
        .ok_or_else(|| ModelFileError::Metadata { detail: "not in the header".into() })?;
    let arch = match metadata.and_then(|m| m.get(ARCHITECTURE_KEY)) {
        None => Architecture::default(),
        Some(json) => serde_json::from_str::<Architecture>(json)
            .map_err(|e| ModelFileError::Architecture { detail: e.to_string() })?,
    };
    if let Some(detail) = arch.problem() {
        return Err(ModelFileError::Architecture { detail });
    }
    let meta: ModelMeta =
        serde_json::from_str(meta_json).map_err(|e| ModelFileError::Metadata { detail: e.to_string() })?;
    if meta.channels.is_empty() || !(meta.dt_s.is_finite() && meta.dt_s > 0.0) || meta.decimation == 0 {
        return Err(ModelFileError::Metadata {
            detail: "needs channels, a positive dt_s and decimation".into(),
        });
    }
    let dim = meta.state.dim();
    if meta.p0_diag.len() != dim || meta.state_units.len() != dim {
        return Err(ModelFileError::Metadata {
            detail: format!(
                "a {} state has {dim} components, but p0_diag has {} and state_units {}",
                meta.state,
                meta.p0_diag.len(),
                meta.state_units.len()
            ),
        });
    }
    let layout = Layout::for_state(meta.state, meta.channels.len(), &arch);
    let mut params = vec![0.0f32; layout.len];
    for e in &layout.entries {
        let bad = |detail: String| ModelFileError::Tensor { name: e.name.clone(), detail };
        let t = st.tensor(&e.name).map_err(|_| bad("missing".into()))?;
        if t.dtype() != Dtype::F32 {
            return Err(bad(format!("dtype {:?}, expected F32", t.dtype())));
        }
        if t.shape() != e.shape.as_slice() {
            return Err(bad(format!("shape {:?}, expected {:?}", t.shape(), e.shape)));
        }
        let v: Vec<f32> =
            t.data().chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        if v.iter().any(|x| !x.is_finite()) {
            return Err(bad("holds NaN or infinity".into()));
        }
        if e.shape.len() == 2 && e.name.ends_with(".weight") {
            let (out, inp) = (e.shape[0], e.shape[1]);
            for o in 0..out {
                for i in 0..inp {
                    params[e.offset + i * out + o] = v[o * inp + i];
                }
            }
        } else {
            params[e.range()].copy_from_slice(&v);
        }
    }
    // L_Q and L_R are lower-triangular.
    for i in layout.upper_triangles() {
        params[i] = 0.0;
    }
    Ok(DekfModel { layout, params, meta })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dekf::Measurement;
    use crate::derivative::DerivativeFilterConfig;
    use rand::SeedableRng;

    fn model() -> DekfModel {
        model_with(&Architecture::default())
    }

    fn model_with(arch: &Architecture) -> DekfModel {
        let meta = ModelMeta {
            dt_s: 0.03,
            decimation: 3,
            tactile_rate_hz: 100.0,
            channels: vec!["thumb.x".into(), "thumb.y".into()],
            measurement: Measurement::Derivative,
            derivative_filter: DerivativeFilterConfig::default(),
            state: crate::dekf::StateKind::Sliding,
            state_units: vec!["cm".into(), "cm/s".into()],
            p0_diag: vec![0.1, 0.1],
            training: serde_json::json!({"note": "test"}),
            software_version: "0".into(),
        };
        DekfModel::with_architecture(meta, arch, &mut rand::rngs::StdRng::seed_from_u64(1))
    }

    /// The metadata of `bytes`' safetensors header.
    fn header_metadata(bytes: &[u8]) -> HashMap<String, String> {
        let (_, header) = SafeTensors::read_metadata(bytes).unwrap();
        header.metadata().clone().unwrap()
    }

    /// `bytes` with its header's metadata replaced by `metadata` (tensors kept).
    fn with_metadata(bytes: &[u8], metadata: HashMap<String, String>) -> Vec<u8> {
        let st = SafeTensors::deserialize(bytes).unwrap();
        let tensors: Vec<(String, TensorView)> = st.tensors();
        safetensors::serialize(tensors, Some(metadata)).unwrap()
    }

    #[test]
    fn the_architecture_is_written_and_read_back() {
        for arch in crate::dekf::mlp::tests::architectures() {
            let m = model_with(&arch);
            let bytes = to_bytes(&m).unwrap();
            let meta = header_metadata(&bytes);
            let written: serde_json::Value = serde_json::from_str(&meta[ARCHITECTURE_KEY]).unwrap();
            assert_eq!(written["width"], arch.width);
            assert_eq!(written["residual_blocks"], arch.residual_blocks);
            assert_eq!(written["activation"], arch.activation.name());
            let back = from_bytes(&bytes).unwrap();
            assert_eq!(back.architecture(), &arch);
            assert_eq!(back, m);
            let st = SafeTensors::deserialize(&bytes).unwrap();
            let shared = st.names().iter().filter(|n| n.starts_with("motion.shared.residual.")).count();
            assert_eq!(shared, 4 * arch.residual_blocks, "{arch:?}");
        }
    }

    /// A file written before the architecture was configurable has no
    /// architecture key: it is the thesis's network, and loads as before.
    #[test]
    fn a_file_without_the_architecture_key_has_the_thesis_network() {
        let m = model();
        let mut meta = header_metadata(&to_bytes(&m).unwrap());
        meta.remove(ARCHITECTURE_KEY);
        let old = with_metadata(&to_bytes(&m).unwrap(), meta);
        let back = from_bytes(&old).unwrap();
        assert_eq!(back.architecture(), &Architecture::default());
        assert_eq!(back, m);
        // A smaller network without the key does not pass for the thesis's.
        let small = model_with(&Architecture { width: 8, ..Architecture::default() });
        let mut meta = header_metadata(&to_bytes(&small).unwrap());
        meta.remove(ARCHITECTURE_KEY);
        let e = from_bytes(&with_metadata(&to_bytes(&small).unwrap(), meta)).unwrap_err();
        assert!(matches!(e, ModelFileError::Tensor { .. }), "{e}");
    }

    #[test]
    fn a_bad_architecture_is_refused_with_the_reason() {
        let m = model();
        for (json, needle) in [
            (r#"{"width": 64, "residual_blocks": 3, "activation": "sigmoid"}"#, "sigmoid"),
            (r#"{"width": 0, "residual_blocks": 3, "activation": "relu"}"#, "width 0"),
            (r#"{"width": 64, "residual_blocks": 1000, "activation": "relu"}"#, "1000"),
            (r#"{"width": 64}"#, "residual_blocks"),
        ] {
            let mut meta = header_metadata(&to_bytes(&m).unwrap());
            meta.insert(ARCHITECTURE_KEY.into(), json.into());
            let e = from_bytes(&with_metadata(&to_bytes(&m).unwrap(), meta)).unwrap_err();
            assert!(
                matches!(e, ModelFileError::Architecture { .. }) && e.to_string().contains(needle),
                "{e}"
            );
        }
        // Tensors of another architecture than the metadata says.
        let tanh = model_with(&Architecture {
            activation: crate::dekf::params::Activation::Tanh,
            residual_blocks: 2,
            ..Architecture::default()
        });
        let mut meta = header_metadata(&to_bytes(&tanh).unwrap());
        meta.insert(ARCHITECTURE_KEY.into(), serde_json::to_string(&Architecture::default()).unwrap());
        let e = from_bytes(&with_metadata(&to_bytes(&tanh).unwrap(), meta)).unwrap_err();
        assert!(e.to_string().contains("shared.residual.2") && e.to_string().contains("missing"), "{e}");
    }

    #[test]
    fn round_trip_keeps_every_parameter_and_the_metadata() {
        let m = model();
        let back = from_bytes(&to_bytes(&m).unwrap()).unwrap();
        assert_eq!(back, m);
    }

    /// Each `HashMap` gets its own random order: without the sorting, some
    /// of twenty serialisations put `format` before the metadata.
    #[test]
    fn the_same_model_gives_the_same_bytes() {
        let m = model();
        let first = to_bytes(&m).unwrap();
        for _ in 0..20 {
            assert!(to_bytes(&m).unwrap() == first);
        }
        assert_eq!(from_bytes(&first).unwrap(), m);
    }

    #[test]
    fn weights_are_stored_row_major_out_by_in() {
        let m = model();
        let bytes = to_bytes(&m).unwrap();
        let st = SafeTensors::deserialize(&bytes).unwrap();
        let t = st.tensor("feature.encoder.linear.weight").unwrap();
        assert_eq!(t.shape(), &[64, 2]);
        let l = *m.layout.feature.linears().next().unwrap();
        // Element [o=5, i=1] of the PyTorch weight.
        let at = (5 * 2 + 1) * 4;
        let v = f32::from_le_bytes(t.data()[at..at + 4].try_into().unwrap());
        assert_eq!(v, m.params[l.weight + 64 + 5]);
    }

    #[test]
    fn bad_files_are_refused_with_the_reason() {
        assert!(matches!(from_bytes(b"garbage"), Err(ModelFileError::Safetensors(_))));
        let m = model();
        let empty: Vec<(&str, TensorView)> = Vec::new();
        let no_meta = safetensors::serialize(empty, None).unwrap();
        assert!(matches!(from_bytes(&no_meta), Err(ModelFileError::Metadata { .. })));
        let mut bytes = to_bytes(&m).unwrap();
        let n = bytes.len();
        bytes.truncate(n - 10);
        assert!(from_bytes(&bytes).is_err());
    }
}
