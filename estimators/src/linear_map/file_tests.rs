//! File checks: round trip bit for bit, stable bytes, the file applied by
//! hand, and bad files refused with the tensor or key named.

use std::collections::HashMap;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};

use super::tests::{gaussian, names};
use super::*;

/// A map with offsets and spreads in its inputs and a `meta` with floats.
fn map() -> LinearMap {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (p, q, n) = (7, 3, 120);
    let x: Vec<f64> =
        gaussian(&mut rng, n * p).iter().enumerate().map(|(k, v)| v * (k % 5) as f64 + 0.3).collect();
    let y: Vec<f64> =
        gaussian(&mut rng, n * q).iter().zip(x.iter().step_by(2)).map(|(e, x)| x + 0.1 * e).collect();
    let groups: Vec<usize> = (0..n).map(|r| r % 8).collect();
    let (mut map, _) =
        LinearMap::fit(&x, &y, &groups, &names("x", p), &names("y", q), &FitOptions::default()).unwrap();
    map.meta["sessions"] = serde_json::json!(["s1", "s2"]);
    map.meta["dt_s"] = serde_json::json!(0.1 + 0.2);
    map
}

/// Owned tensors of a file: name → (dtype, shape, bytes).
type Tensors = HashMap<String, (Dtype, Vec<usize>, Vec<u8>)>;

fn tensors(bytes: &[u8]) -> Tensors {
    let st = SafeTensors::deserialize(bytes).unwrap();
    st.tensors().into_iter().map(|(n, t)| (n, (t.dtype(), t.shape().to_vec(), t.data().to_vec()))).collect()
}

fn metadata(bytes: &[u8]) -> HashMap<String, String> {
    SafeTensors::read_metadata(bytes).unwrap().1.metadata().clone().unwrap()
}

/// A file of `tensors` and `metadata`.
fn file(tensors: &Tensors, metadata: HashMap<String, String>) -> Vec<u8> {
    let views: Vec<(&str, TensorView)> = tensors
        .iter()
        .map(|(n, (dtype, shape, data))| (n.as_str(), TensorView::new(*dtype, shape.clone(), data).unwrap()))
        .collect();
    safetensors::serialize(views, Some(metadata)).unwrap()
}

fn values(data: &[u8]) -> Vec<f64> {
    data.chunks_exact(8).map(|b| f64::from_le_bytes(b.try_into().unwrap())).collect()
}

/// Catches: values or names lost or rounded (e.g. stored as F32, or `W`
/// rebuilt from `W'·σ`), `meta` dropped.
#[test]
fn a_map_read_back_is_the_same_map_and_gives_the_same_outputs_bit_for_bit() {
    let m = map();
    let back = LinearMap::from_bytes(&m.to_bytes().unwrap()).unwrap();
    assert_eq!(back, m);
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let (mut a, mut b) = (vec![0.0; 3], vec![0.0; 3]);
    for x in gaussian(&mut rng, 50 * 7).chunks(7) {
        m.apply(x, &mut a);
        back.apply(x, &mut b);
        assert!(a.iter().zip(&b).all(|(a, b)| a.to_bits() == b.to_bits()), "{a:?} vs {b:?}");
    }
}

/// Each `HashMap` has its own order: without the sorted header some of
/// twenty serialisations differ.
#[test]
fn the_same_map_gives_the_same_bytes() {
    let m = map();
    let first = m.to_bytes().unwrap();
    for _ in 0..20 {
        assert!(m.to_bytes().unwrap() == first);
    }
    let meta = metadata(&first);
    assert_eq!(meta[FORMAT_KEY], FORMAT);
    assert_eq!(meta["input_names"], r#"["x0","x1","x2","x3","x4","x5","x6"]"#);
}

/// Catches: `linear.weight` stored column-major or on standardised inputs,
/// a bias without the standardisation folded in.
#[test]
fn the_file_applied_by_hand_equals_apply() {
    let m = map();
    let t = tensors(&m.to_bytes().unwrap());
    let (dtype, shape, w) = &t["linear.weight"];
    assert_eq!((*dtype, shape.as_slice()), (Dtype::F64, &[3, 7][..]));
    let (w, b) = (values(w), values(&t["linear.bias"].2));
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let mut out = vec![0.0; 3];
    for x in gaussian(&mut rng, 50 * 7).chunks(7) {
        m.apply(x, &mut out);
        for o in 0..3 {
            let by_hand = b[o] + (0..7).map(|i| w[o * 7 + i] * x[i]).sum::<f64>();
            assert!((by_hand - out[o]).abs() < 1e-12 * (1.0 + out[o].abs()), "{by_hand} vs {}", out[o]);
        }
    }
}

fn tensor_error(bytes: &[u8]) -> (&'static str, String) {
    match LinearMap::from_bytes(bytes) {
        Err(LinearMapError::Tensor { name, detail }) => (name, detail),
        other => panic!("expected a tensor error, got {other:?}"),
    }
}

/// Catches: unchecked tensors (a missing one, a wrong shape or dtype, NaN,
/// a zero spread) and a `linear.*` that disagrees with the standardised form.
#[test]
fn bad_tensors_are_refused_naming_the_tensor() {
    let good = map().to_bytes().unwrap();
    let (t, meta) = (tensors(&good), metadata(&good));
    let edited = |edit: &dyn Fn(&mut Tensors)| {
        let mut t = t.clone();
        edit(&mut t);
        file(&t, meta.clone())
    };
    let set = |name: &'static str, at: usize, v: f64| {
        edited(&move |t: &mut Tensors| {
            t.get_mut(name).unwrap().2[at * 8..at * 8 + 8].copy_from_slice(&v.to_le_bytes());
        })
    };
    let cases: Vec<(Vec<u8>, &str, &str)> = vec![
        (edited(&|t| drop(t.remove("linear.bias"))), "linear.bias", "missing"),
        (edited(&|t| t.get_mut("input_mean").unwrap().1 = vec![1, 7]), "input_mean", "shape"),
        (
            edited(&|t| {
                let e = t.get_mut("output_mean").unwrap();
                *e = (Dtype::F32, vec![3], vec![0; 12]);
            }),
            "output_mean",
            "dtype",
        ),
        (set("standardised.weight", 4, f64::NAN), "standardised.weight", "NaN"),
        (set("linear.weight", 2, f64::INFINITY), "linear.weight", "inf"),
        (set("input_std", 1, 0.0), "input_std", "positive"),
        (set("linear.weight", 5, 123.0), "linear.weight", "standardised"),
        (set("linear.bias", 0, 9.0), "linear.bias", "standardised"),
    ];
    for (bytes, name, needle) in cases {
        let (got, detail) = tensor_error(&bytes);
        assert_eq!(got, name, "{detail}");
        assert!(detail.contains(needle), "{name}: {detail}");
    }
}

/// Catches: garbage or foreign files read as maps, metadata unchecked.
#[test]
fn bad_files_and_metadata_are_refused() {
    assert!(matches!(LinearMap::from_bytes(b"garbage"), Err(LinearMapError::Safetensors(_))));
    let good = map().to_bytes().unwrap();
    assert!(LinearMap::from_bytes(&good[..good.len() - 10]).is_err());
    let t = tensors(&good);
    let with = |key: &str, value: Option<&str>| {
        let mut meta = metadata(&good);
        match value {
            Some(v) => meta.insert(key.into(), v.into()),
            None => meta.remove(key),
        };
        LinearMap::from_bytes(&file(&t, meta))
    };
    for (key, value) in [
        ("format", None),
        ("format", Some("slidetrack-dekf-1")),
        ("input_names", Some(r#"["x0","x1"]"#)), // 2 names, tensors for 7: a shape error
        ("output_names", Some(r#"["y0","y0","y2"]"#)),
        ("lambda", Some("[1.0, -1.0, 2.0]")),
        ("lambda", Some("[1.0]")),
        ("meta", Some("{not json")),
        ("input_names", None),
    ] {
        match with(key, value) {
            Err(LinearMapError::Metadata { key: k, .. }) => assert_eq!(k, key),
            Err(LinearMapError::Tensor { name, detail }) if key == "input_names" && value.is_some() => {
                assert!(detail.contains("shape"), "{name}: {detail}");
            }
            other => panic!("{key} = {value:?}: {other:?}"),
        }
    }
}
