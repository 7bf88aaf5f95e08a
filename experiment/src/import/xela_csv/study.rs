//! The numbers of `docs/real-data.md` ("The xela-imanlab recordings"),
//! computed from the real files. `findings_hold` checks the claims the page
//! makes; the ignored `print_real_data_tables` prints the page's tables:
//!
//! ```text
//! cargo test -p slidetrack-experiment import::xela_csv::study -- --ignored --nocapture
//! ```

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::{Matrix3, Quaternion, SymmetricEigen, UnitQuaternion, Vector3};

use super::*;

fn all_sequences() -> Vec<XelaSequence> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/testdata/tactile/xela-imanlab");
    read_sequences(&[root.join("train"), root.join("test")]).unwrap()
}

/// Rows of a sequence, including the tactile tail.
fn tactile_rows(seq: &XelaSequence, sensor: usize) -> Vec<&PatchCounts> {
    seq.frames.iter().map(|f| &f.tactile[sensor]).chain(&seq.tail.tactile[sensor]).collect()
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

fn sorted(mut v: Vec<f64>) -> Vec<f64> {
    v.sort_by(f64::total_cmp);
    v
}

/// Frame intervals estimated from the joints (s): `dt = Σ Δq·v / Σ v²`
/// over the seven joints, `v` the mean of the two rows' measured joint
/// velocities, on row pairs where `|v| >= 0.5 rad/s` (slower motion gives
/// too noisy an estimate).
fn joint_intervals_s(seq: &XelaSequence) -> Vec<f64> {
    seq.frames
        .windows(2)
        .filter_map(|w| {
            let (a, b) = (&w[0].robot, &w[1].robot);
            let (mut dq_v, mut v_v) = (0.0, 0.0);
            for j in 0..7 {
                let v = 0.5 * (a.joint_velocity_rad_s[j] + b.joint_velocity_rad_s[j]);
                dq_v += (b.joint_position_rad[j] - a.joint_position_rad[j]) * v;
                v_v += v * v;
            }
            (v_v >= 0.25).then(|| dq_v / v_v)
        })
        .collect()
}

/// Rows at which sensor 1's counts differ from the previous row's.
fn tactile_changes(seq: &XelaSequence) -> usize {
    tactile_rows(seq, 0).windows(2).filter(|w| w[0] != w[1]).count()
}

/// Rows at which the two sensors change at different rows.
fn tactile_changes_disagreeing(seq: &XelaSequence) -> usize {
    let (a, b) = (tactile_rows(seq, 0), tactile_rows(seq, 1));
    a.windows(2).zip(b.windows(2)).filter(|(x, y)| (x[0] != x[1]) != (y[0] != y[1])).count()
}

fn duration_s(seq: &XelaSequence) -> f64 {
    seq.meta.stop_time_s - seq.meta.start_time_s
}

/// Longest run of consecutive frames in which marker `m` is not seen, and the
/// run that ends the sequence (frames).
fn unseen_runs(seq: &XelaSequence, m: usize) -> (usize, usize) {
    let (mut longest, mut run) = (0, 0);
    for frame in &seq.frames {
        run = if frame.markers[m].is_none() { run + 1 } else { 0 };
        longest = longest.max(run);
    }
    (longest, run)
}

fn seen(seq: &XelaSequence, m: usize) -> Vec<&MarkerPose> {
    seq.frames.iter().filter_map(|f| f.markers[m].as_ref()).collect()
}

fn position(p: &MarkerPose) -> Vector3<f64> {
    Vector3::from(p.position_in_camera_m)
}

fn rotation(q: [f64; 4]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2]))
}

/// Max minus min of each coordinate (m).
fn extent(points: &[Vector3<f64>]) -> Vector3<f64> {
    if points.is_empty() {
        return Vector3::repeat(f64::NAN);
    }
    let (mut lo, mut hi) = (points[0], points[0]);
    for p in points {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    hi - lo
}

fn ee_positions(seq: &XelaSequence) -> Vec<Vector3<f64>> {
    seq.frames.iter().map(|f| Vector3::from(f.robot.ee_position_in_base_m)).collect()
}

/// Marker 2 in marker 1's frame (m), on frames that see both.
fn marker2_in_marker1(seq: &XelaSequence) -> Vec<Vector3<f64>> {
    seq.frames
        .iter()
        .filter_map(|f| {
            let (m1, m2) = (f.markers[0].as_ref()?, f.markers[1].as_ref()?);
            Some(rotation(m1.orientation_in_camera_xyzw).inverse() * (position(m2) - position(m1)))
        })
        .collect()
}

fn mean(points: &[Vector3<f64>]) -> Vector3<f64> {
    points.iter().sum::<Vector3<f64>>() / points.len() as f64
}

/// Root mean square distance to the mean (m).
fn spread(points: &[Vector3<f64>]) -> f64 {
    let mu = mean(points);
    (points.iter().map(|p| (p - mu).norm_squared()).sum::<f64>() / points.len() as f64).sqrt()
}

/// 95th percentile of the distances to the per-axis median (m): the
/// spread of a point set, blind to a few outliers.
fn spread_p95(points: &[Vector3<f64>]) -> f64 {
    let median = Vector3::from_fn(|i, _| {
        let axis = sorted(points.iter().map(|p| p[i]).collect());
        percentile(&axis, 0.5)
    });
    percentile(&sorted(points.iter().map(|p| (p - median).norm()).collect()), 0.95)
}

/// Marker 2 in marker 1's frame on the frames that see both and where
/// marker 1 is more than 1 cm from its first sighting (the object has moved
/// in the hand).
fn marker2_in_marker1_moved(seq: &XelaSequence) -> Vec<Vector3<f64>> {
    let Some(first) = seen(seq, 0).first().map(|p| position(p)) else {
        return Vec::new();
    };
    seq.frames
        .iter()
        .filter_map(|f| {
            let (m1, m2) = (f.markers[0].as_ref()?, f.markers[1].as_ref()?);
            let moved = (position(m1) - first).norm() > 0.01;
            moved.then(|| rotation(m1.orientation_in_camera_xyzw).inverse() * (position(m2) - position(m1)))
        })
        .collect()
}

/// Principal direction of a point set: the unit eigenvector of the largest
/// eigenvalue of its covariance, and that eigenvalue's share of the total.
fn principal_axis(points: &[Vector3<f64>]) -> (Vector3<f64>, f64) {
    let mu = mean(points);
    let cov = points.iter().map(|p| (p - mu) * (p - mu).transpose()).sum::<Matrix3<f64>>();
    let eig = SymmetricEigen::new(cov);
    let i = eig.eigenvalues.imax();
    (eig.eigenvectors.column(i).into_owned(), eig.eigenvalues[i] / eig.eigenvalues.sum())
}

/// Marker 1's track relative to its first sighting (m, camera frame).
fn marker1_displacements(seq: &XelaSequence) -> Vec<Vector3<f64>> {
    let track: Vec<Vector3<f64>> = seen(seq, 0).into_iter().map(position).collect();
    track.iter().map(|p| p - track[0]).collect()
}

/// Marker 1's outward normal (its z axis) at its first sighting, camera frame.
fn marker1_normal(seq: &XelaSequence) -> Vector3<f64> {
    rotation(seen(seq, 0)[0].orientation_in_camera_xyzw) * Vector3::z()
}

/// Index of the first frame at which the gripper is within 1 mm of its
/// narrowest opening of the first half of the sequence (the grasp).
fn grasp_frame(seq: &XelaSequence) -> usize {
    let half = &seq.frames[..seq.frames.len() / 2];
    let narrowest = half.iter().map(|f| f.robot.finger_position_m).fold(f64::INFINITY, f64::min);
    half.iter().position(|f| f.robot.finger_position_m < narrowest + 0.001).unwrap_or(0)
}

/// Mean counts of `rows` per taxel and axis.
fn mean_counts(rows: &[&PatchCounts]) -> [[f64; 3]; TAXELS] {
    let mut out = [[0.0; 3]; TAXELS];
    for row in rows {
        for (o, r) in out.iter_mut().zip(row.iter()) {
            for a in 0..3 {
                o[a] += f64::from(r[a]) / rows.len() as f64;
            }
        }
    }
    out
}

/// Per taxel and axis: counts after the grasp (mean of 20 rows from the
/// grasp frame) minus before (mean of the first 10 rows).
fn grasp_response(seq: &XelaSequence, sensor: usize) -> [[f64; 3]; TAXELS] {
    let rows = tactile_rows(seq, sensor);
    let g = grasp_frame(seq);
    let (before, after) = (mean_counts(&rows[..10]), mean_counts(&rows[g..(g + 20).min(rows.len())]));
    std::array::from_fn(|t| std::array::from_fn(|a| after[t][a] - before[t][a]))
}

fn degrees_between(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    a.angle(b).to_degrees()
}

fn short(seq: &XelaSequence) -> &str {
    seq.name.trim_start_matches("data_sample_2021-")
}

fn cm(v: &Vector3<f64>) -> String {
    format!("{:.1}, {:.1}, {:.1}", 100.0 * v.x, 100.0 * v.y, 100.0 * v.z)
}

fn unit(v: &Vector3<f64>) -> String {
    format!("({:+.2}, {:+.2}, {:+.2})", v.x, v.y, v.z)
}

#[test]
fn findings_hold() {
    let sequences = all_sequences();
    for seq in &sequences {
        let name = &seq.name;
        // Tactile counts change every ~4 rows (~10 Hz; 7.5 Hz in the two
        // sequences recorded at 32 Hz), both sensors at the same rows.
        let tactile_hz = tactile_changes(seq) as f64 / duration_s(seq);
        assert!((7.0..11.0).contains(&tactile_hz), "{name}: {tactile_hz}");
        assert_eq!(tactile_changes_disagreeing(seq), 0, "{name}");
        // The robot state changes every row.
        assert!(seq.frames.windows(2).all(|w| w[0].robot != w[1].robot), "{name}");
        // Wrist camera: unless the object falls, marker 1 moves less than a
        // tenth of what the end effector moves.
        let ee = extent(&ee_positions(seq)).norm();
        let m1: Vec<Vector3<f64>> = seen(seq, 0).into_iter().map(position).collect();
        assert!(seq.meta.dropped || extent(&m1).norm() < 0.1 * ee, "{name}");
        // Both markers on one rigid body: marker 2 in marker 1's frame stays
        // put: 95 % of frames within 6 mm of the median (3 mm or less in
        // most sequences), while the markers move by centimetres.
        let rel = marker2_in_marker1(seq);
        if rel.len() >= 10 {
            assert!(spread_p95(&rel) < 0.006, "{name}: {}", spread_p95(&rel));
        }
    }
    let dropped: Vec<&XelaSequence> = sequences.iter().filter(|s| s.meta.dropped).collect();
    assert_eq!(dropped.len(), 14);
    // ... also while the object has moved in the hand (marker 1 > 1 cm away
    // from where it was first seen), per sequence.
    for seq in &sequences {
        let moved = marker2_in_marker1_moved(seq);
        if moved.len() >= 10 {
            assert!(spread_p95(&moved) < 0.006, "{}: {}", seq.name, spread_p95(&moved));
        }
    }
    // Marker 1 stays within 2 cm of its first sighting in 31 of the 39
    // sequences that keep the object, and leaves it in every dropped one.
    let max_displacement =
        |s: &XelaSequence| marker1_displacements(s).iter().map(|d| d.norm()).fold(0.0, f64::max);
    let kept = sequences.iter().filter(|s| !s.meta.dropped);
    assert_eq!(kept.filter(|s| max_displacement(s) < 0.02).count(), 31);
    assert!(dropped.iter().all(|s| max_displacement(s) > 0.02));
}

#[test]
#[ignore = "prints the tables of docs/real-data.md"]
fn print_real_data_tables() {
    let sequences = all_sequences();
    let mut out = String::new();
    rate_table(&sequences, &mut out);
    tactile_tables(&sequences, &mut out);
    camera_table(&sequences, &mut out);
    marker_tables(&sequences, &mut out);
    moved_rigidity(&sequences, &mut out);
    sliding_tables(&sequences, &mut out);
    println!("{out}");
}

fn rate_table(sequences: &[XelaSequence], out: &mut String) {
    writeln!(out, "\n## Rates\n").unwrap();
    writeln!(
        out,
        "| sequence | rows | tail | duration s | frequency_hz | tactile Hz | dt n | dt p5/p50/p95 ms \
         | 1/2/3/4+ of 1/60 s |"
    )
    .unwrap();
    writeln!(out, "|---|---|---|---|---|---|---|---|---|").unwrap();
    let mut all = Vec::new();
    for seq in sequences {
        let dts = sorted(joint_intervals_s(seq));
        all.extend_from_slice(&dts);
        let bins = frame_bins(&dts);
        writeln!(
            out,
            "| {} | {} | {} | {:.2} | {:.2} | {:.2} | {} | {:.0}/{:.0}/{:.0} | {bins} |",
            short(seq),
            seq.frames.len(),
            seq.tail.tactile[0].len(),
            duration_s(seq),
            seq.meta.frequency_hz,
            tactile_changes(seq) as f64 / duration_s(seq),
            dts.len(),
            1e3 * percentile(&dts, 0.05),
            1e3 * percentile(&dts, 0.5),
            1e3 * percentile(&dts, 0.95),
        )
        .unwrap();
    }
    let all = sorted(all);
    let bins = frame_bins(&all);
    writeln!(
        out,
        "\nall: n {} p5/p50/p95 {:.1}/{:.1}/{:.1} ms; bins {bins}",
        all.len(),
        1e3 * percentile(&all, 0.05),
        1e3 * percentile(&all, 0.5),
        1e3 * percentile(&all, 0.95)
    )
    .unwrap();
    let rows: usize = sequences.iter().map(|s| s.frames.len()).sum();
    let total_s: f64 = sequences.iter().map(duration_s).sum();
    writeln!(out, "rows {rows}, duration {total_s:.1} s, mean rate {:.2} Hz", rows as f64 / total_s).unwrap();
    let mut hist = [0_usize; 120];
    for dt in &all {
        hist[((dt * 1e3).round() as usize).min(119)] += 1;
    }
    writeln!(
        out,
        "histogram (ms: count): {:?}",
        hist.iter().enumerate().filter(|(_, c)| **c > 0).collect::<Vec<_>>()
    )
    .unwrap();
}

/// Shares (%) of intervals nearest 1, 2, 3 and 4 or more periods of 60 Hz.
fn frame_bins(dts: &[f64]) -> String {
    let mut bins = [0_usize; 4];
    for dt in dts {
        bins[((dt * 60.0).round().max(1.0) as usize - 1).min(3)] += 1;
    }
    let share = |n: usize| 100.0 * n as f64 / dts.len().max(1) as f64;
    format!("{:.0}/{:.0}/{:.0}/{:.0}", share(bins[0]), share(bins[1]), share(bins[2]), share(bins[3]))
}

fn tactile_tables(sequences: &[XelaSequence], out: &mut String) {
    writeln!(out, "\n## Tactile\n").unwrap();
    for sensor in 0..SENSORS {
        let (mut lo, mut hi) = ([u16::MAX; 3], [0_u16; 3]);
        let mut baseline_lo = [f64::INFINITY; 3];
        let mut baseline_hi = [f64::NEG_INFINITY; 3];
        let mut response = [[0.0; 3]; TAXELS];
        for seq in sequences {
            for row in tactile_rows(seq, sensor) {
                for taxel in row {
                    for a in 0..3 {
                        lo[a] = lo[a].min(taxel[a]);
                        hi[a] = hi[a].max(taxel[a]);
                    }
                }
            }
            for taxel in mean_counts(&tactile_rows(seq, sensor)[..10]) {
                for a in 0..3 {
                    baseline_lo[a] = baseline_lo[a].min(taxel[a]);
                    baseline_hi[a] = baseline_hi[a].max(taxel[a]);
                }
            }
            for (r, g) in response.iter_mut().zip(grasp_response(seq, sensor)) {
                for a in 0..3 {
                    r[a] += g[a] / sequences.len() as f64;
                }
            }
        }
        writeln!(out, "sensor {}: min {lo:?} max {hi:?} (x, y, z)", sensor + 1).unwrap();
        writeln!(
            out,
            "  baseline (first 10 rows, per taxel) x {:.0}..{:.0}, y {:.0}..{:.0}, z {:.0}..{:.0}",
            baseline_lo[0], baseline_hi[0], baseline_lo[1], baseline_hi[1], baseline_lo[2], baseline_hi[2]
        )
        .unwrap();
        for (a, axis) in ["x", "y", "z"].iter().enumerate() {
            let grid: Vec<String> = (0..4)
                .map(|r| {
                    (0..4).map(|c| format!("{:+5.0}", response[4 * r + c][a])).collect::<Vec<_>>().join(" ")
                })
                .collect();
            writeln!(out, "  mean grasp response {axis} (txl1-4 | 5-8 | 9-12 | 13-16): {}", grid.join(" | "))
                .unwrap();
        }
    }
}

fn camera_table(sequences: &[XelaSequence], out: &mut String) {
    writeln!(out, "\n## Camera: extents (max - min, cm)\n").unwrap();
    writeln!(out, "| sequence | object | dropped | end effector x, y, z | marker 1 | marker 2 |").unwrap();
    writeln!(out, "|---|---|---|---|---|---|").unwrap();
    for seq in sequences {
        let m1: Vec<Vector3<f64>> = seen(seq, 0).into_iter().map(position).collect();
        let m2: Vec<Vector3<f64>> = seen(seq, 1).into_iter().map(position).collect();
        writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} |",
            short(seq),
            seq.meta.object_name,
            u8::from(seq.meta.dropped),
            cm(&extent(&ee_positions(seq))),
            cm(&extent(&m1)),
            if m2.is_empty() { "-".into() } else { cm(&extent(&m2)) },
        )
        .unwrap();
    }
}

fn marker_tables(sequences: &[XelaSequence], out: &mut String) {
    writeln!(out, "\n## Markers\n").unwrap();
    writeln!(
        out,
        "| sequence | object | seen 1 % | seen 2 % | longest gap 1 | longest gap 2 | trailing gap 1 \
         | depth 1/2 cm | marker 2 in marker 1 cm | rms / p95 mm | normals deg |"
    )
    .unwrap();
    writeln!(out, "|---|---|---|---|---|---|---|---|---|---|---|").unwrap();
    for seq in sequences {
        let n = seq.frames.len() as f64;
        let ((gap1, trail1), (gap2, _)) = (unseen_runs(seq, 0), unseen_runs(seq, 1));
        let depth = |m: usize| {
            let s = seen(seq, m);
            if s.is_empty() {
                f64::NAN
            } else {
                100.0 * s.iter().map(|p| p.position_in_camera_m[2]).sum::<f64>() / s.len() as f64
            }
        };
        let rel = marker2_in_marker1(seq);
        let normals: Vec<f64> = seq
            .frames
            .iter()
            .filter_map(|f| {
                let (a, b) = (f.markers[0].as_ref()?, f.markers[1].as_ref()?);
                let z = Vector3::z();
                Some(degrees_between(
                    &(rotation(a.orientation_in_camera_xyzw) * z),
                    &(rotation(b.orientation_in_camera_xyzw) * z),
                ))
            })
            .collect();
        let (rel_text, rms, angle) = if rel.is_empty() {
            ("-".to_owned(), "-".to_owned(), "-".to_owned())
        } else {
            (
                cm(&mean(&rel)),
                format!("{:.1} / {:.1}", 1e3 * spread(&rel), 1e3 * spread_p95(&rel)),
                format!("{:.0}", normals.iter().sum::<f64>() / normals.len() as f64),
            )
        };
        let period = 1.0 / seq.meta.frequency_hz;
        writeln!(
            out,
            "| {} | {} | {:.0} | {:.0} | {gap1} ({:.1} s) | {gap2} ({:.1} s) | {trail1} | {:.1}/{:.1} | {rel_text} | {rms} | {angle} |",
            short(seq),
            seq.meta.object_name,
            100.0 * seen(seq, 0).len() as f64 / n,
            100.0 * seen(seq, 1).len() as f64 / n,
            gap1 as f64 * period,
            gap2 as f64 * period,
            depth(0),
            depth(1),
        )
        .unwrap();
    }
}

fn moved_rigidity(sequences: &[XelaSequence], out: &mut String) {
    let mut total = 0;
    for seq in sequences {
        let moved = marker2_in_marker1_moved(seq);
        let all = marker2_in_marker1(seq);
        if moved.len() >= 10 {
            let shift = 100.0 * (mean(&moved) - mean(&all)).norm();
            writeln!(
                out,
                "moved {}: n {} p95 {:.1} mm, mean shift vs all frames {shift:.2} cm",
                short(seq),
                moved.len(),
                1e3 * spread_p95(&moved)
            )
            .unwrap();
        }
        total += moved.len();
    }
    writeln!(out, "moved total frames {total}").unwrap();
}

fn sliding_tables(sequences: &[XelaSequence], out: &mut String) {
    writeln!(out, "\n## Sliding: marker 1 relative to its first sighting (camera frame)\n").unwrap();
    writeln!(
        out,
        "| sequence | dropped | last seen at % | displacement there cm | max ‖d‖ cm | principal axis \
         | explained % | angle to -normal deg | axis in marker 1 frame | rotation there deg |"
    )
    .unwrap();
    writeln!(out, "|---|---|---|---|---|---|---|---|---|---|").unwrap();
    let mut pooled = Vec::new();
    let mut pooled_dropped = Vec::new();
    for seq in sequences {
        let d = marker1_displacements(seq);
        let (mut axis, explained) = principal_axis(&d);
        let last = *d.last().unwrap_or(&Vector3::zeros());
        if axis.dot(&last) < 0.0 {
            axis = -axis;
        }
        let normal = marker1_normal(seq);
        let object_from_camera = rotation(seen(seq, 0)[0].orientation_in_camera_xyzw).inverse();
        let last_seen = seq.frames.iter().rposition(|f| f.markers[0].is_some()).unwrap_or(0);
        let max_d = d.iter().map(|v| v.norm()).fold(0.0, f64::max);
        let track = seen(seq, 0);
        let (q0, q1) =
            (track[0].orientation_in_camera_xyzw, track[track.len() - 1].orientation_in_camera_xyzw);
        let turned = rotation(q0).angle_to(&rotation(q1)).to_degrees();
        writeln!(
            out,
            "| {} | {} | {:.0} | {} | {:.1} | {} | {:.0} | {:.0} | {} | {turned:.0} |",
            short(seq),
            u8::from(seq.meta.dropped),
            100.0 * last_seen as f64 / seq.frames.len() as f64,
            cm(&last),
            100.0 * max_d,
            unit(&axis),
            100.0 * explained,
            degrees_between(&axis, &-normal),
            unit(&(object_from_camera * axis)),
        )
        .unwrap();
        pooled.extend_from_slice(&d);
        if seq.meta.dropped {
            pooled_dropped.extend_from_slice(&d);
        }
    }
    for (what, points) in [("all", &pooled), ("dropped", &pooled_dropped)] {
        let (mut axis, explained) = principal_axis(points);
        if axis.dot(&mean(points)) < 0.0 {
            axis = -axis;
        }
        writeln!(out, "\npooled {what}: axis {} explained {:.0} %", unit(&axis), 100.0 * explained).unwrap();
    }
}
