//! Sliding episodes in a track of the object's velocity.

/// One stretch of sliding between two sticks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Episode {
    /// Start time (s).
    pub start_s: f64,
    /// End time (s).
    pub end_s: f64,
    /// Travel during the episode (m).
    pub travel_m: f64,
    /// Peak speed (m/s).
    pub peak_speed_mps: f64,
}

/// Finds the sliding episodes of a track of `(t_s, position_m, velocity_mps)`.
///
/// A sample slides when its speed exceeds `speed_threshold_mps`; slides
/// separated by less than `min_stick_s` of sticking are one episode; an
/// episode counts when it travels at least `min_travel_m`.
pub fn sliding_episodes(
    track: &[(f64, f64, f64)],
    speed_threshold_mps: f64,
    min_stick_s: f64,
    min_travel_m: f64,
) -> Vec<Episode> {
    let mut raw: Vec<(usize, usize)> = Vec::new();
    let mut start = None;
    for (i, &(_, _, v)) in track.iter().enumerate() {
        let sliding = v.abs() > speed_threshold_mps;
        match (sliding, start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                raw.push((s, i - 1));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        raw.push((s, track.len() - 1));
    }
    let mut merged: Vec<(usize, usize)> = Vec::new();
    for (s, e) in raw {
        match merged.last_mut() {
            Some(last) if track[s].0 - track[last.1].0 < min_stick_s => last.1 = e,
            _ => merged.push((s, e)),
        }
    }
    merged
        .into_iter()
        .map(|(s, e)| Episode {
            start_s: track[s].0,
            end_s: track[e].0,
            travel_m: track[e].1 - track[s.saturating_sub(1)].1,
            peak_speed_mps: track[s..=e].iter().map(|x| x.2.abs()).fold(0.0, f64::max),
        })
        .filter(|ep| ep.travel_m.abs() >= min_travel_m)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_separate_and_merges_close_slides() {
        // Slides at 1-2 s and 2.2-3 s (merged), and at 5-6 s; 100 Hz.
        let mut track = Vec::new();
        let mut p = 0.0;
        for k in 0..800 {
            let t = k as f64 * 0.01;
            let v = if (1.0..2.0).contains(&t) || (2.2..3.0).contains(&t) || (5.0..6.0).contains(&t) {
                0.01
            } else {
                0.0
            };
            p += v * 0.01;
            track.push((t, p, v));
        }
        let eps = sliding_episodes(&track, 1e-3, 0.5, 1e-3);
        assert_eq!(eps.len(), 2, "{eps:?}");
        assert!((eps[0].travel_m - 0.018).abs() < 1e-3);
        assert!((eps[1].start_s - 5.0).abs() < 0.011);
    }
}
