//! The tables of `slidetrack study`, laid out as thesis Tables 6.1-6.4:
//! rows bottle, mustard, box and MEAN (the mean over objects).

use std::collections::BTreeMap;

use serde_json::{Value, json};

use crate::dekf_run::Scores;

/// The objects, in the thesis's row order.
pub const OBJECTS: [&str; 3] = ["bottle", "mustard", "box"];

/// Scores of one model on one object's sets.
#[derive(Clone, Debug)]
struct Entry {
    train: Option<Scores>,
    test: Scores,
}

/// Every score the study computed, by `(model, tested object)`.
#[derive(Default)]
pub struct Tables {
    entries: BTreeMap<(String, String), Entry>,
}

/// The baselines of one object's xy model on its testing data.
struct Baselines {
    zero_position_cm: Option<f64>,
    zero_velocity_cmps: Option<f64>,
    linear_position_cm: Option<f64>,
    linear_velocity_cmps: Option<f64>,
    /// The dEKF's position RMSE over zero motion's.
    over_zero: Option<f64>,
    /// The dEKF's position RMSE over the linear map's.
    over_linear: Option<f64>,
}

/// A scalar of [`Scores`].
type Metric = fn(&Scores) -> f64;
const POS_RMSE: Metric = |s| s.position_rmse_cm;
const POS_MAX: Metric = |s| s.position_max_cm;
const VEL_RMSE: Metric = |s| s.velocity_rmse_cmps;
const VEL_MAX: Metric = |s| s.velocity_max_cmps;

/// A table's layout: title, header lines (one entry per column each) and cells.
type Layout = (&'static str, Vec<Vec<String>>, Vec<Cell>);

/// A cell: a model's testing (or training) score on an object.
#[derive(Clone, Copy)]
struct Cell {
    model: &'static str,
    train: bool,
    metric: Metric,
}

fn cell(model: &'static str, train: bool, metric: Metric) -> Cell {
    Cell { model, train, metric }
}

impl Tables {
    /// Records the scores of `model` on `object`'s testing set (and training set).
    pub fn record(&mut self, model: &str, object: &str, train: Option<Scores>, test: Scores) {
        self.entries.insert((model.to_string(), object.to_string()), Entry { train, test });
    }

    /// The value of `c` for the row of `object`; `model` may hold `{o}` for the object.
    fn value(&self, c: Cell, object: &str) -> Option<f64> {
        let model = c.model.replace("{o}", object);
        let e = self.entries.get(&(model, object.to_string()))?;
        let s = if c.train { e.train.as_ref()? } else { &e.test };
        Some((c.metric)(s))
    }

    /// Rows bottle, mustard, box, MEAN of `cells`.
    fn rows(&self, cells: &[Cell]) -> Vec<(String, Vec<Option<f64>>)> {
        let mut rows: Vec<(String, Vec<Option<f64>>)> = OBJECTS
            .iter()
            .map(|o| (o.to_string(), cells.iter().map(|c| self.value(*c, o)).collect()))
            .collect();
        let mean = (0..cells.len())
            .map(|i| {
                let v: Option<Vec<f64>> = rows.iter().map(|r| r.1[i]).collect();
                v.map(|v| v.iter().sum::<f64>() / v.len() as f64)
            })
            .collect();
        rows.push(("MEAN".into(), mean));
        rows
    }

    /// The four tables' cells: `(title, header lines, cells)`.
    fn layouts() -> Vec<Layout> {
        let metrics = [POS_RMSE, POS_MAX, VEL_RMSE, VEL_MAX];
        let four =
            |m: &'static str, train: bool| metrics.iter().map(|f| cell(m, train, *f)).collect::<Vec<_>>();
        let by_metric = |models: &[&'static str], ms: &[Metric]| {
            ms.iter().flat_map(|f| models.iter().map(move |m| cell(m, false, *f))).collect::<Vec<_>>()
        };
        let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
        let rep =
            |names: &[&str], n: usize| (0..n).flat_map(|_| names.iter().map(|x| x.to_string())).collect();
        let metric_names = s(&["pos RMSE (cm)", "pos max (cm)", "vel RMSE (cm/s)", "vel max (cm/s)"]);
        vec![
            (
                "Table 6.1: training and testing errors, xyz channels",
                vec![
                    [vec!["training".to_string(); 4], vec!["testing".to_string(); 4]].concat(),
                    [metric_names.clone(), metric_names.clone()].concat(),
                ],
                [four("{o}-xyz", true), four("{o}-xyz", false)].concat(),
            ),
            (
                "Table 6.2: testing errors by tactile channels",
                vec![
                    metric_names.iter().flat_map(|m| vec![m.clone(); 3]).collect(),
                    rep(&["xyz", "xy", "z"], 4),
                ],
                by_metric(&["{o}-xyz", "{o}-xy", "{o}-z"], &metrics),
            ),
            (
                "Table 6.3: testing errors, xy channels, plain signal (tau) or its derivative (dtau)",
                vec![
                    metric_names.iter().flat_map(|m| vec![m.clone(); 2]).collect(),
                    rep(&["tau", "dtau"], 4),
                ],
                by_metric(&["{o}-xy-raw", "{o}-xy"], &metrics),
            ),
            (
                "Table 6.4: testing RMSE, xy channels, by training set (rows: tested object)",
                vec![
                    [
                        vec!["pos RMSE (cm), trained on".to_string(); 4],
                        vec!["vel RMSE (cm/s), trained on".to_string(); 4],
                    ]
                    .concat(),
                    rep(&["bottle", "mustard", "box", "all"], 2),
                ],
                by_metric(&["bottle-xy", "mustard-xy", "box-xy", "all-xy"], &[POS_RMSE, VEL_RMSE]),
            ),
        ]
    }

    /// The baselines of the xy models on their testing data, per object:
    /// zero motion (position and velocity RMSE), the linear map, and the
    /// dEKF's position RMSE over each.
    fn baselines(&self) -> Vec<(String, Baselines)> {
        OBJECTS
            .iter()
            .map(|o| {
                let e = self.entries.get(&(format!("{o}-xy"), o.to_string())).map(|e| &e.test);
                let ratio = |d: Option<f64>| e.zip(d).map(|(e, d)| e.position_rmse_cm / d.max(1e-12));
                let b = Baselines {
                    zero_position_cm: e.map(|e| e.baseline_position_rmse_cm),
                    zero_velocity_cmps: e.map(|e| e.baseline_velocity_rmse_cmps),
                    linear_position_cm: e.and_then(|e| e.linear_position_rmse_cm),
                    linear_velocity_cmps: e.and_then(|e| e.linear_velocity_rmse_cmps),
                    over_zero: ratio(e.map(|e| e.baseline_position_rmse_cm)),
                    over_linear: ratio(e.and_then(|e| e.linear_position_rmse_cm)),
                };
                (o.to_string(), b)
            })
            .collect()
    }

    /// The tables in Markdown, with the study's settings.
    pub fn markdown(&self, config: &Value) -> String {
        let fmt = |v: &Option<f64>| v.map_or("-".to_string(), |x| format!("{x:.3}"));
        let mut out = format!("# dEKF study on the simulated rig\n\nsettings: `{config}`\n");
        for (title, headers, cells) in Self::layouts() {
            out += &format!("\n## {title}\n\n");
            for (k, h) in headers.iter().enumerate() {
                out += &format!(
                    "| {} | {} |\n",
                    if k + 1 == headers.len() { "data set" } else { "" },
                    h.join(" | ")
                );
                if k == 0 {
                    out += &format!("|---|{}\n", "---:|".repeat(h.len()));
                }
            }
            for (name, values) in self.rows(&cells) {
                out += &format!("| {name} | {} |\n", values.iter().map(fmt).collect::<Vec<_>>().join(" | "));
            }
        }
        out += "\n## Baselines on the xy models' testing data: zero motion (p = 0, v = 0) and the linear map \
                on the same channels and training sessions\n\n| data set | zero pos RMSE (cm) | zero vel RMSE (cm/s) | \
                linear pos RMSE (cm) | linear vel RMSE (cm/s) | xy dEKF / zero | xy dEKF / linear |\n\
                |---|---:|---:|---:|---:|---:|---:|\n";
        let pct = |r: Option<f64>| r.map_or("-".into(), |r| format!("{:.0} %", r * 100.0));
        for (o, b) in self.baselines() {
            out += &format!(
                "| {o} | {} | {} | {} | {} | {} | {} |\n",
                fmt(&b.zero_position_cm),
                fmt(&b.zero_velocity_cmps),
                fmt(&b.linear_position_cm),
                fmt(&b.linear_velocity_cmps),
                pct(b.over_zero),
                pct(b.over_linear)
            );
        }
        out
    }

    /// The tables as JSON: per table, per row, the cells with their column names.
    pub fn json(&self) -> Value {
        let mut tables = serde_json::Map::new();
        for (title, headers, cells) in Self::layouts() {
            let columns: Vec<String> = (0..cells.len())
                .map(|i| headers.iter().map(|h| h[i].as_str()).collect::<Vec<_>>().join(" / "))
                .collect();
            let rows: serde_json::Map<String, Value> = self
                .rows(&cells)
                .into_iter()
                .map(|(name, values)| {
                    let row: serde_json::Map<String, Value> =
                        columns.iter().zip(values).map(|(c, v)| (c.clone(), json!(v))).collect();
                    (name, Value::Object(row))
                })
                .collect();
            let key = title.split(':').next().unwrap_or(title).to_string();
            tables.insert(key, json!({"title": title, "columns": columns, "rows": rows}));
        }
        let baseline: serde_json::Map<String, Value> = self
            .baselines()
            .into_iter()
            .map(|(o, b)| {
                let v = json!({
                    "baseline_position_rmse_cm": b.zero_position_cm,
                    "baseline_velocity_rmse_cmps": b.zero_velocity_cmps,
                    "linear_position_rmse_cm": b.linear_position_cm,
                    "linear_velocity_rmse_cmps": b.linear_velocity_cmps,
                    "xy_ratio": b.over_zero,
                    "xy_over_linear": b.over_linear,
                });
                (o, v)
            })
            .collect();
        tables.insert("baseline".into(), Value::Object(baseline));
        Value::Object(tables)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scores(p: f64) -> Scores {
        Scores { position_rmse_cm: p, baseline_position_rmse_cm: 2.0, ..Scores::default() }
    }

    #[test]
    fn tables_have_the_thesis_rows_and_columns_and_the_mean_over_objects() {
        let mut t = Tables::default();
        for (k, o) in OBJECTS.iter().enumerate() {
            for m in ["xyz", "xy", "z", "xy-raw"] {
                t.record(&format!("{o}-{m}"), o, Some(scores(0.1)), scores(1.0 + k as f64));
            }
        }
        let j = t.json();
        let t2 = &j["Table 6.2"];
        assert_eq!(t2["columns"].as_array().map(Vec::len), Some(12));
        let rows: Vec<&String> = t2["rows"].as_object().map(|r| r.keys().collect()).unwrap_or_default();
        assert_eq!(rows.len(), 4);
        assert_eq!(t2["rows"]["MEAN"]["pos RMSE (cm) / xyz"], json!(2.0));
        assert_eq!(j["Table 6.1"]["columns"].as_array().map(Vec::len), Some(8));
        assert_eq!(j["Table 6.3"]["columns"].as_array().map(Vec::len), Some(8));
        // No cross-object scores recorded: Table 6.4 off the diagonal is empty, its MEAN too.
        assert_eq!(j["Table 6.4"]["rows"]["box"]["pos RMSE (cm), trained on / box"], json!(3.0));
        assert_eq!(j["Table 6.4"]["rows"]["box"]["pos RMSE (cm), trained on / mustard"], Value::Null);
        assert!(t.markdown(&json!({})).contains("| MEAN | 0.100 |"));
    }
}
