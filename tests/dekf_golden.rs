//! Both Python twins of the dEKF network against the golden file
//! (`tests/golden/`, docs/model-format.md "The golden file"): the NumPy
//! implementation of the model format (`tests/python/dekf_reference.py`)
//! and the independent PyTorch training (`scripts/dekf_torch_train.py`, its
//! own `Net` and `run_filter`). slidetrack's own two executors are checked
//! against the same file by `estimators/src/dekf/golden.rs`.
//!
//! The file holds three small models (sliding ReLU with two shared blocks,
//! sliding tanh with none, planar GELU with three outputs), their networks'
//! values and Jacobians at a few inputs, and twelve filter steps. A layer
//! swapped or left out, a wrong activation, a transposed weight or a wrong
//! normalisation moves the outputs by 1e-2 or more; the float32 roundings
//! of the twins (another summation order, BLAS) by below 1e-6.

mod common;

use std::path::Path;
use std::process::Command;

use common::python;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// Networks in float32, as slidetrack's: a few ulps apart (measured: below
/// 2e-7 relative to `max(|value|, 1)`).
const NETWORK_TOLERANCE: f64 = 1e-5;

/// The NumPy filter runs in float64 on float32 networks, as slidetrack's:
/// the networks' roundings carried over twelve steps (measured: below 5e-7).
const NUMPY_FILTER_TOLERANCE: f64 = 1e-5;

/// The PyTorch filter runs in float32 throughout, as the twin trains: its
/// own roundings of `F P F^T + Q` and the gain on top (measured: below 4e-7;
/// a tenfold margin more than NumPy's for other CPUs' float32 kernels).
const TORCH_FILTER_TOLERANCE: f64 = 1e-4;

fn golden() -> String {
    format!("{ROOT}/tests/golden/dekf.json")
}

/// Runs `python SCRIPT ARGS` and returns its JSON report.
fn report(python: &Path, script: &str, args: &[&str]) -> serde_json::Value {
    let out = Command::new(python).arg(format!("{ROOT}/{script}")).args(args).output().expect("python runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{script} failed:\n{stderr}");
    serde_json::from_slice(&out.stdout).expect("JSON from the twin")
}

/// The value of `key` in a model's report (`null`: not checked).
fn difference(model: &serde_json::Value, key: &str) -> Option<f64> {
    model[key].as_f64()
}

#[test]
fn the_numpy_reference_reproduces_the_golden_file() {
    let r = report(&python(), "tests/python/dekf_reference.py", &["--check-golden", &golden()]);
    let models = r["models"].as_array().expect("models");
    assert_eq!(models.len(), 3, "{r}");
    for m in models {
        let name = &m["name"];
        assert!(difference(m, "network").expect("network") < NETWORK_TOLERANCE, "{name}: {m}");
        for key in ["mean", "covariance"] {
            assert!(difference(m, key).expect("filter") < NUMPY_FILTER_TOLERANCE, "{name} {key}: {m}");
        }
        assert_eq!(m["corrected_as_golden"], true, "{name}: {m}");
    }
}

#[test]
fn the_torch_twin_reproduces_the_golden_file() {
    let python = python();
    let has_torch =
        Command::new(&python).args(["-c", "import torch"]).output().is_ok_and(|o| o.status.success());
    if !has_torch {
        eprintln!(
            "SKIPPED the_torch_twin_reproduces_the_golden_file: {} has no torch; `scripts/setup.sh --test` \
             (which `scripts/test` runs) installs it into target/pyenv",
            python.display()
        );
        return;
    }
    let r = report(&python, "scripts/dekf_torch_train.py", &["--check-golden", &golden()]);
    let models = r["models"].as_array().expect("models");
    assert_eq!(models.len(), 3, "{r}");
    for m in models {
        let name = &m["name"];
        assert!(difference(m, "network").expect("network") < NETWORK_TOLERANCE, "{name}: {m}");
        // The twin's filter is the thesis's sliding one; a planar model has
        // its networks checked only.
        let sliding = name.as_str().is_some_and(|n| n.starts_with("sliding"));
        for key in ["mean", "covariance"] {
            match difference(m, key) {
                Some(d) => assert!(d < TORCH_FILTER_TOLERANCE, "{name} {key}: {m}"),
                None => assert!(!sliding, "{name}: the filter of a sliding model is checked: {m}"),
            }
        }
    }
}
