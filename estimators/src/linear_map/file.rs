//! The map file (format in the [`linear_map`](crate::linear_map) docs). Bytes in,
//! bytes out.

use std::collections::HashMap;

use nalgebra::DMatrix;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};

use super::error::LinearMapError;
use super::map::LinearMap;

/// Metadata key holding the format version.
pub const FORMAT_KEY: &str = "format";
/// The format written.
pub const FORMAT: &str = "slidetrack-linear-1";

const INPUT_NAMES: &str = "input_names";
const OUTPUT_NAMES: &str = "output_names";
const LAMBDA: &str = "lambda";
const META: &str = "meta";

const WEIGHT: &str = "linear.weight";
const BIAS: &str = "linear.bias";
const STANDARDISED_WEIGHT: &str = "standardised.weight";
const INPUT_MEAN: &str = "input_mean";
const INPUT_STD: &str = "input_std";
const OUTPUT_MEAN: &str = "output_mean";

/// Row-major values of an `[outputs, inputs]` matrix.
fn row_major(m: &DMatrix<f64>) -> Vec<f64> {
    m.transpose().as_slice().to_vec()
}

fn le_bytes(values: &[f64]) -> Vec<u8> {
    values.iter().flat_map(|x| x.to_le_bytes()).collect()
}

impl LinearMap {
    /// The map as safetensors bytes (format in the [`linear_map`](crate::linear_map) docs).
    ///
    /// # Errors
    /// Only if safetensors refuses the tensors (a bug).
    pub fn to_bytes(&self) -> Result<Vec<u8>, LinearMapError> {
        let (p, q) = (self.inputs(), self.outputs());
        let (w, b) = self.affine();
        let tensors: Vec<(&str, Vec<usize>, Vec<u8>)> = vec![
            (WEIGHT, vec![q, p], le_bytes(&row_major(&w))),
            (BIAS, vec![q], le_bytes(b.as_slice())),
            (STANDARDISED_WEIGHT, vec![q, p], le_bytes(&row_major(&self.weights))),
            (INPUT_MEAN, vec![p], le_bytes(&self.input_mean)),
            (INPUT_STD, vec![p], le_bytes(&self.input_std)),
            (OUTPUT_MEAN, vec![q], le_bytes(&self.output_mean)),
        ];
        let views = tensors
            .iter()
            .map(|(name, shape, bytes)| Ok((*name, TensorView::new(Dtype::F64, shape.clone(), bytes)?)))
            .collect::<Result<Vec<_>, safetensors::SafeTensorError>>()?;
        let json = |key: &'static str, value: serde_json::Result<String>| {
            value
                .map(|v| (key.to_string(), v))
                .map_err(|e| LinearMapError::Metadata { key, detail: e.to_string() })
        };
        let info = HashMap::from([
            (FORMAT_KEY.to_string(), FORMAT.to_string()),
            json(INPUT_NAMES, serde_json::to_string(&self.input_names))?,
            json(OUTPUT_NAMES, serde_json::to_string(&self.output_names))?,
            json(LAMBDA, serde_json::to_string(&self.lambda))?,
            json(META, serde_json::to_string(&self.meta))?,
        ]);
        Ok(crate::dekf::file::with_sorted_header(safetensors::serialize(views, Some(info))?))
    }

    /// A map from bytes written by [`LinearMap::to_bytes`] (or by any tool
    /// following the format in the [`linear_map`](crate::linear_map) docs).
    ///
    /// # Errors
    /// Not safetensors; a metadata entry missing or wrong (which key, what);
    /// a tensor missing, not `F64`, of the wrong shape, holding NaN or
    /// infinity, a non-positive `input_std`, or `linear.*` disagreeing with
    /// the standardised form (which tensor, what).
    pub fn from_bytes(bytes: &[u8]) -> Result<LinearMap, LinearMapError> {
        let st = SafeTensors::deserialize(bytes)?;
        let (_, header) = SafeTensors::read_metadata(bytes)?;
        let empty = HashMap::new();
        let metadata = header.metadata().as_ref().unwrap_or(&empty);
        let entry = |key: &'static str| {
            metadata.get(key).ok_or(LinearMapError::Metadata { key, detail: "not in the header".into() })
        };
        let format = entry(FORMAT_KEY)?;
        if format != FORMAT {
            return Err(LinearMapError::Metadata {
                key: FORMAT_KEY,
                detail: format!("`{format}`, expected `{FORMAT}`"),
            });
        }
        let input_names = names(INPUT_NAMES, "input", entry(INPUT_NAMES)?)?;
        let output_names = names(OUTPUT_NAMES, "output", entry(OUTPUT_NAMES)?)?;
        let (p, q) = (input_names.len(), output_names.len());
        let lambda: Vec<f64> = parse(LAMBDA, entry(LAMBDA)?)?;
        if lambda.len() != q || lambda.iter().any(|l| !(l.is_finite() && *l > 0.0)) {
            return Err(LinearMapError::Metadata {
                key: LAMBDA,
                detail: format!("{lambda:?}: expected {q} finite positive penalties"),
            });
        }
        let meta = parse(META, entry(META)?)?;
        let input_std = tensor(&st, INPUT_STD, &[p])?;
        if let Some(s) = input_std.iter().find(|s| **s <= 0.0) {
            return Err(LinearMapError::Tensor {
                name: INPUT_STD,
                detail: format!("holds {s}, must be positive"),
            });
        }
        let weights = tensor(&st, STANDARDISED_WEIGHT, &[q, p])?;
        let map = LinearMap {
            input_names,
            output_names,
            input_mean: tensor(&st, INPUT_MEAN, &[p])?,
            input_std,
            output_mean: tensor(&st, OUTPUT_MEAN, &[q])?,
            weights: DMatrix::from_row_slice(q, p, &weights),
            lambda,
            meta,
        };
        map.check_affine(&tensor(&st, WEIGHT, &[q, p])?, &tensor(&st, BIAS, &[q])?)?;
        Ok(map)
    }

    /// Checks that the file's `linear.weight` and `linear.bias` are this
    /// map's [`LinearMap::affine`] (up to a writer's rounding, 1e-9).
    fn check_affine(&self, weight: &[f64], bias: &[f64]) -> Result<(), LinearMapError> {
        let (w, b) = self.affine();
        for ((o, i), expected) in
            (0..self.outputs()).flat_map(|o| (0..self.inputs()).map(move |i| (o, i))).zip(weight)
        {
            let got = w[(o, i)];
            if (got - expected).abs() > 1e-9 * got.abs().max(expected.abs()) {
                return Err(LinearMapError::Tensor {
                    name: WEIGHT,
                    detail: format!(
                        "[{o}, {i}] = {expected}, but standardised.weight / input_std gives {got}"
                    ),
                });
            }
        }
        for (o, expected) in bias.iter().enumerate() {
            let scale = self.output_mean[o].abs()
                + (0..self.inputs()).map(|i| (w[(o, i)] * self.input_mean[i]).abs()).sum::<f64>();
            if (b[o] - expected).abs() > 1e-9 * scale {
                return Err(LinearMapError::Tensor {
                    name: BIAS,
                    detail: format!("[{o}] = {expected}, but the standardised form gives {}", b[o]),
                });
            }
        }
        Ok(())
    }
}

fn parse<T: serde::de::DeserializeOwned>(key: &'static str, json: &str) -> Result<T, LinearMapError> {
    serde_json::from_str(json).map_err(|e| LinearMapError::Metadata { key, detail: e.to_string() })
}

fn names(key: &'static str, what: &'static str, json: &str) -> Result<Vec<String>, LinearMapError> {
    let names: Vec<String> = parse(key, json)?;
    super::fit::names(what, &names).map_err(|e| LinearMapError::Metadata { key, detail: e.to_string() })
}

/// The values of the `F64` tensor `name` of shape `shape`, all finite.
fn tensor(st: &SafeTensors<'_>, name: &'static str, shape: &[usize]) -> Result<Vec<f64>, LinearMapError> {
    let bad = |detail: String| LinearMapError::Tensor { name, detail };
    let t = st.tensor(name).map_err(|_| bad("missing".into()))?;
    if t.dtype() != Dtype::F64 {
        return Err(bad(format!("dtype {:?}, expected F64", t.dtype())));
    }
    if t.shape() != shape {
        return Err(bad(format!("shape {:?}, expected {shape:?}", t.shape())));
    }
    let values: Vec<f64> = t
        .data()
        .chunks_exact(8)
        .map(|b| <[u8; 8]>::try_from(b).map_or(f64::NAN, f64::from_le_bytes))
        .collect();
    if let Some(at) = values.iter().position(|x| !x.is_finite()) {
        return Err(bad(format!("element {at} is {}", values[at])));
    }
    Ok(values)
}
