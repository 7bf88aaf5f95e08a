//! Scores as result files hold them: a number that is not finite (a NaN
//! RMSE of a diverged model, an infinite maximum) is written as the string
//! `"NaN"`, `"inf"` or `"-inf"`, because JSON has no such numbers and
//! `serde_json` would write `null`, which no longer reads back as a number:
//! the job would look unfinished forever.

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::dekf_run::Scores;

/// A float that survives JSON: finite as a number, else as text.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(untagged)]
enum Float {
    Number(f64),
    Text(String),
}

impl Float {
    fn of(x: f64) -> Float {
        if x.is_finite() {
            Float::Number(x)
        } else if x.is_nan() {
            Float::Text("NaN".into())
        } else if x > 0.0 {
            Float::Text("inf".into())
        } else {
            Float::Text("-inf".into())
        }
    }

    fn value<E: serde::de::Error>(self) -> Result<f64, E> {
        match self {
            Float::Number(x) => Ok(x),
            Float::Text(t) => match t.as_str() {
                "NaN" => Ok(f64::NAN),
                "inf" => Ok(f64::INFINITY),
                "-inf" => Ok(f64::NEG_INFINITY),
                other => Err(E::custom(format!("`{other}` is not a number (nor NaN, inf, -inf)"))),
            },
        }
    }
}

/// [`Scores`] with every float as a [`Float`].
#[derive(Serialize, Deserialize)]
struct Stored {
    position_rmse_cm: Float,
    position_max_cm: Float,
    velocity_rmse_cmps: Float,
    velocity_max_cmps: Float,
    baseline_position_rmse_cm: Float,
    baseline_velocity_rmse_cmps: Float,
    linear_position_rmse_cm: Option<Float>,
    linear_velocity_rmse_cmps: Option<Float>,
    steps: usize,
}

impl From<&Scores> for Stored {
    fn from(s: &Scores) -> Stored {
        // Every field named: a field added to `Scores` fails to compile here.
        let Scores {
            position_rmse_cm,
            position_max_cm,
            velocity_rmse_cmps,
            velocity_max_cmps,
            baseline_position_rmse_cm,
            baseline_velocity_rmse_cmps,
            linear_position_rmse_cm,
            linear_velocity_rmse_cmps,
            steps,
        } = s.clone();
        Stored {
            position_rmse_cm: Float::of(position_rmse_cm),
            position_max_cm: Float::of(position_max_cm),
            velocity_rmse_cmps: Float::of(velocity_rmse_cmps),
            velocity_max_cmps: Float::of(velocity_max_cmps),
            baseline_position_rmse_cm: Float::of(baseline_position_rmse_cm),
            baseline_velocity_rmse_cmps: Float::of(baseline_velocity_rmse_cmps),
            linear_position_rmse_cm: linear_position_rmse_cm.map(Float::of),
            linear_velocity_rmse_cmps: linear_velocity_rmse_cmps.map(Float::of),
            steps,
        }
    }
}

impl Stored {
    fn scores<E: serde::de::Error>(self) -> Result<Scores, E> {
        let opt = |f: Option<Float>| f.map(Float::value::<E>).transpose();
        Ok(Scores {
            position_rmse_cm: self.position_rmse_cm.value()?,
            position_max_cm: self.position_max_cm.value()?,
            velocity_rmse_cmps: self.velocity_rmse_cmps.value()?,
            velocity_max_cmps: self.velocity_max_cmps.value()?,
            baseline_position_rmse_cm: self.baseline_position_rmse_cm.value()?,
            baseline_velocity_rmse_cmps: self.baseline_velocity_rmse_cmps.value()?,
            linear_position_rmse_cm: opt(self.linear_position_rmse_cm)?,
            linear_velocity_rmse_cmps: opt(self.linear_velocity_rmse_cmps)?,
            steps: self.steps,
        })
    }
}

/// `#[serde(with = "scores")]` for a [`Scores`] field.
pub mod scores {
    use super::*;

    /// Writes `s` with its non-finite numbers as text.
    pub fn serialize<S: Serializer>(s: &Scores, serializer: S) -> Result<S::Ok, S::Error> {
        Stored::from(s).serialize(serializer)
    }

    /// Reads what [`serialize`] wrote.
    pub fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Scores, D::Error> {
        Stored::deserialize(deserializer)?.scores()
    }
}

/// `#[serde(with = "optional_scores")]` for an `Option<Scores>` field.
pub mod optional_scores {
    use super::*;

    /// Writes `s` (or `null`) with its non-finite numbers as text.
    pub fn serialize<S: Serializer>(s: &Option<Scores>, serializer: S) -> Result<S::Ok, S::Error> {
        s.as_ref().map(Stored::from).serialize(serializer)
    }

    /// Reads what [`serialize`] wrote.
    pub fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Option<Scores>, D::Error> {
        Option::<Stored>::deserialize(deserializer)?.map(Stored::scores).transpose()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize, Deserialize)]
    struct Row {
        #[serde(with = "scores")]
        test: Scores,
        #[serde(with = "optional_scores")]
        train: Option<Scores>,
    }

    #[test]
    fn non_finite_scores_read_back_as_written() {
        let s = Scores {
            position_rmse_cm: f64::NAN,
            position_max_cm: f64::INFINITY,
            velocity_rmse_cmps: 1.25,
            velocity_max_cmps: f64::NEG_INFINITY,
            linear_position_rmse_cm: Some(f64::NAN),
            steps: 7,
            ..Scores::default()
        };
        let text = serde_json::to_string(&Row { test: s.clone(), train: None }).expect("writes");
        assert!(text.contains(r#""position_rmse_cm":"NaN""#), "{text}");
        assert!(text.contains(r#""linear_position_rmse_cm":"NaN""#), "{text}");
        let back: Row = serde_json::from_str(&text).expect("reads back");
        assert!(back.test.position_rmse_cm.is_nan());
        assert!(back.test.linear_position_rmse_cm.is_some_and(f64::is_nan));
        assert_eq!(back.test.linear_velocity_rmse_cmps, None);
        assert_eq!(back.test.position_max_cm, f64::INFINITY);
        assert_eq!(back.test.velocity_max_cmps, f64::NEG_INFINITY);
        assert_eq!((back.test.velocity_rmse_cmps, back.test.steps), (1.25, 7));
        assert!(back.train.is_none());
        let bad = text.replace(r#""NaN""#, r#""nan?""#);
        let e = serde_json::from_str::<Row>(&bad).err().expect("unknown text is an error");
        assert!(e.to_string().contains("nan?"), "{e}");
    }
}
