//! `collect --rig hw` with the serial tactile backend reading the simulated
//! rig through a real pseudo-terminal (`port = "emulated"`), compared with
//! the simulated rig itself; and the device vanishing mid-trial.

mod common;

use std::path::Path;

use common::{
    SERIAL_EMULATED, SHORT_PROTOCOL, SIM_PATCH_4X4, assert_ended_by_disconnect, fails, ok, slidetrack,
    tempdir,
};
use slidetrack_session::{
    ReadOptions, SessionInfo, TactileDecoder, TactileRaw, TactileZeroed, TaxelLayout, read_channel,
};

fn write_rig(dir: &Path, extra: &str) -> String {
    let path = dir.join("rig.toml");
    // A 4x4 patch per fingertip read as three 16-taxel modules, and the
    // simulated camera.
    let camera = "[hw.camera]\nkind = \"sim\"\n";
    std::fs::write(&path, format!("{SHORT_PROTOCOL}{SIM_PATCH_4X4}{SERIAL_EMULATED}{camera}{extra}"))
        .expect("rig.toml written");
    path.to_str().expect("a UTF-8 path").to_string()
}

fn collect(rig: &str, kind: &str, out: &Path) {
    let out = out.to_str().expect("a UTF-8 path");
    let args = [
        "-q",
        "collect",
        "--rig",
        kind,
        "--config",
        rig,
        "--object",
        "box",
        "--duration",
        "2",
        "--seed",
        "3",
    ];
    ok(&[&args[..], &["--no-camera", "--out", out]].concat());
}

fn topics(file: &Path) -> Vec<String> {
    let info = SessionInfo::read(file, ReadOptions::default()).expect("a readable session");
    let mut t: Vec<String> = info.channels.iter().map(|c| c.topic.clone()).collect();
    t.sort();
    t
}

fn mean_std(xs: impl Iterator<Item = f64>) -> (f64, f64) {
    let v: Vec<f64> = xs.collect();
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64;
    (mean, var.sqrt())
}

#[test]
fn collect_through_a_real_tty_gives_the_session_of_the_simulated_rig() {
    let dir = tempdir();
    let rig = write_rig(dir.path(), "");
    let (hw_dir, sim_dir) = (dir.path().join("hw"), dir.path().join("sim"));
    collect(&rig, "hw", &hw_dir);
    collect(&rig, "sim", &sim_dir);
    let (hw, sim) = (hw_dir.join("box-s3-t000.mcap"), sim_dir.join("box-s3-t000.mcap"));

    // The same channels, plus the decoder's counters.
    let mut expected = topics(&sim);
    expected.push("/tactile/decoder".into());
    expected.sort();
    assert_eq!(topics(&hw), expected);
    let hw_info = SessionInfo::read(&hw, ReadOptions::default()).unwrap();
    let outcome = &hw_info.metadata["slidetrack.outcome"];
    assert_eq!(outcome["completed"], "true", "{outcome:?}");
    assert_eq!(hw_info.metadata["slidetrack"]["rig"], "emulated-serial");

    // The layout names the tty and the finger map.
    let raw_channel = hw_info.channels.iter().find(|c| c.topic == "/tactile/raw").unwrap();
    let layout = TaxelLayout::from_channel_metadata(&raw_channel.metadata).unwrap().unwrap();
    assert!(layout.device.starts_with("/dev/pts/"), "{}", layout.device);
    let grids: Vec<(String, u32, u32)> =
        layout.sensors.iter().map(|s| (s.name.clone(), s.rows, s.cols)).collect();
    assert_eq!(grids, ["thumb", "index", "middle"].map(|n| (n.to_string(), 4, 4)));
    assert_eq!(layout.fingers.middle, slidetrack_core::FingerReading::mean("middle"));

    let hw_raw = read_channel::<TactileRaw>(&hw, ReadOptions::default()).unwrap();
    let sim_raw = read_channel::<TactileRaw>(&sim, ReadOptions::default()).unwrap();
    let (n_hw, n_sim) = (hw_raw.len() as f64, sim_raw.len() as f64);
    assert!((n_hw - n_sim).abs() / n_sim < 0.1, "{n_hw} scans through the tty, {n_sim} simulated");
    let rate = raw_channel.mean_rate_hz.unwrap();
    assert!((rate - 100.0).abs() < 5.0, "{rate} Hz");

    // While the hand is open (zeroing) the data do not depend on timing:
    // the bytes through the tty carry exactly the simulated scans.
    for ((_, a), (_, b)) in hw_raw.iter().zip(&sim_raw).take(45) {
        assert_eq!(a, b);
    }
    let identical = hw_raw.iter().zip(&sim_raw).filter(|((_, a), (_, b))| a == b).count();
    eprintln!("{identical} of {n_sim} scans identical to the simulated rig's");

    // The grasp: per finger, the baseline-subtracted normal channel has the
    // simulated rig's statistics.
    let zeroed = |f: &Path| read_channel::<TactileZeroed>(f, ReadOptions::default()).unwrap();
    let (hw_z, sim_z) = (zeroed(&hw), zeroed(&sim));
    for finger in 0..3 {
        let z = |v: &[(slidetrack_core::TimeNs, TactileZeroed)]| {
            // The finger's reading: the mean z of its patch.
            mean_std(v.iter().map(|(_, m)| m.sensors[finger].taxels.iter().map(|t| t.z).sum::<f64>() / 16.0))
        };
        let ((mh, sh), (ms, ss)) = (z(&hw_z), z(&sim_z));
        assert!((mh - ms).abs() < 0.1 * ss.max(10.0) + 0.05 * ms.abs(), "finger {finger}: mean {mh} vs {ms}");
        assert!((sh - ss).abs() < 0.15 * ss.max(10.0), "finger {finger}: std {sh} vs {ss}");
    }

    let counters = read_channel::<TactileDecoder>(&hw, ReadOptions::default()).unwrap();
    let (_, last) = counters.last().unwrap();
    assert_eq!((last.crc_errors, last.resyncs, last.gaps, last.incomplete_scans), (0, 0, 0, 0), "{last:?}");
    assert!(last.frames >= 3 * hw_raw.len() as u64, "three modules per scan: {last:?}");
}

#[test]
fn unplugging_mid_trial_releases_the_hand_and_keeps_the_data() {
    let dir = tempdir();
    let faults =
        "emulator = { unplug_after_s = 2.5, corrupt_every_frames = 40, garbage_every_frames = 55 }\n";
    let rig = dir.path().join("rig.toml");
    let text = format!("{SHORT_PROTOCOL}{SIM_PATCH_4X4}{SERIAL_EMULATED}")
        .replace("port = \"emulated\"\n", &format!("port = \"emulated\"\n{faults}"));
    std::fs::write(&rig, text).unwrap();
    let out = dir.path().join("out");
    let output = slidetrack()
        .args(["-q", "collect", "--rig", "hw", "--config", rig.to_str().unwrap(), "--duration", "20"])
        .args(["--no-camera", "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains("disconnected") && stderr.contains("/dev/pts/"), "{stderr}");
    assert!(stderr.contains("the hand was released") && stderr.contains("scans recorded so far"), "{stderr}");
    assert_eq!(stderr.matches("/dev/pts/").count(), 1, "one message about the device: {stderr}");

    // A complete file (no --recover needed) with the data up to the unplug.
    let file = out.join("box-s1-t000.mcap");
    assert_ended_by_disconnect(&file, 150..=260);
    // The injected faults are counted.
    let (_, last) = read_channel::<TactileDecoder>(&file, ReadOptions::default()).unwrap().pop().unwrap();
    assert!(last.crc_errors >= 5 && last.resyncs >= 5 && last.incomplete_scans >= 5, "{last:?}");
}

#[test]
fn missing_devices_and_configs_give_one_clear_line() {
    let dir = tempdir();
    let out = dir.path().join("out");
    let out = out.to_str().unwrap();
    let e = fails(&["collect", "--rig", "hw", "--duration", "1", "--out", out]);
    assert!(e.contains("[hw]") && e.contains("--config"), "{e}");

    let rig = dir.path().join("rig.toml");
    std::fs::write(&rig, "[hw.tactile]\nkind = \"serial\"\nport = \"/dev/ttyNOSUCH9\"\n").unwrap();
    let e = fails(&[
        "collect",
        "--rig",
        "hw",
        "--config",
        rig.to_str().unwrap(),
        "--duration",
        "1",
        "--out",
        out,
    ]);
    assert!(e.contains("/dev/ttyNOSUCH9") && e.contains("cannot open"), "{e}");

    std::fs::write(&rig, "[hw.tactile]\nkind = \"can\"\ninterface = \"nosuchcan7\"\n").unwrap();
    let e = fails(&[
        "collect",
        "--rig",
        "hw",
        "--config",
        rig.to_str().unwrap(),
        "--duration",
        "1",
        "--out",
        out,
    ]);
    assert!(e.contains("nosuchcan7"), "{e}");

    std::fs::write(&rig, "[hw.tactile]\nkind = \"serial\"\nport = \"emulated\"\n[hw.hand]\nkind = \"can\"\n")
        .unwrap();
    let e = fails(&[
        "collect",
        "--rig",
        "hw",
        "--config",
        rig.to_str().unwrap(),
        "--duration",
        "1",
        "--out",
        out,
    ]);
    assert!(e.contains("emulated") && e.contains("sim"), "{e}");
}
