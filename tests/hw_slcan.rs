//! `collect --rig hw` with the CAN tactile backend reading the simulated
//! rig through an SLCAN adapter emulated on a pseudo-terminal
//! (`slcan = { port = "emulated" }`): every taxel of every sensor reaches
//! `/tactile/raw` as the simulated sensors produced it, in the legacy
//! layout and in an explicit id map; and the adapter vanishing mid-trial.

mod common;

use std::path::{Path, PathBuf};

use common::{SHORT_PROTOCOL, SIM_PATCH_4X4, assert_ended_by_disconnect, ok, slidetrack, tempdir};
use slidetrack_session::{ReadOptions, SessionInfo, TactileDecoder, TactileRaw, TaxelLayout, read_channel};

/// Three 4x4 patches (the default sensors, modules 0-2) in the legacy
/// layout: taxel t of module m at 0x710 + 16 m + t.
const SLCAN_LEGACY: &str = "
[hw]
name = \"emulated-slcan\"
[hw.tactile]
kind = \"can\"
slcan = { port = \"emulated\" }
fingers = { thumb = { sensor = \"thumb\" }, index = { sensor = \"index\" }, middle = { sensor = \"middle\" } }
[hw.hand]
kind = \"sim\"
[hw.camera]
kind = \"sim\"
";

/// The same sensors in an explicit map with gaps, a row/column pattern,
/// single ids, little-endian values at other offsets, extended ids, a
/// validity byte, and start and stop frames.
const SLCAN_MAP: &str = "
[hw]
name = \"emulated-slcan-map\"
[hw.tactile]
kind = \"can\"
slcan = { port = \"emulated\", timestamps = false }
fingers = { thumb = { sensor = \"thumb\" }, index = { sensor = \"index\" }, middle = { sensor = \"middle\" } }
start = { id = 0x100, data = [1] }
stop = { id = 0x100, data = [0] }
payload = { byte_order = \"little\", x = 2, y = 4, z = 6, valid = { byte = 0, below = 1 } }
[[hw.tactile.map]]
sensor = \"thumb\"
base_id = 0x400
row_stride = 0x10
col_stride = 2
[[hw.tactile.map]]
sensor = \"index\"
first_id = 0x500
count = 15
id_step = 3
[[hw.tactile.map]]
sensor = \"index\"
id = 0x5FF
taxel = 15
[[hw.tactile.map]]
sensor = \"middle\"
first_id = 0x18FF0000
extended = true
[hw.hand]
kind = \"sim\"
[hw.camera]
kind = \"sim\"
";

fn write_rig(dir: &Path, hw: &str) -> String {
    let path = dir.join("rig.toml");
    std::fs::write(&path, format!("{SHORT_PROTOCOL}{SIM_PATCH_4X4}{hw}")).expect("rig.toml written");
    path.to_str().expect("a UTF-8 path").to_string()
}

fn collect(rig: &str, kind: &str, out: &Path) -> PathBuf {
    let out_text = out.to_str().expect("a UTF-8 path");
    let args = ["-q", "collect", "--rig", kind, "--config", rig, "--object", "box", "--duration", "2"];
    ok(&[&args[..], &["--seed", "3", "--no-camera", "--out", out_text]].concat());
    out.join("box-s3-t000.mcap")
}

/// Collects through the emulated adapter and on the simulated rig, and
/// checks the CAN session holds every taxel of every sensor as simulated.
fn records_every_taxel_as_simulated(hw: &str, rig_name: &str) {
    let dir = tempdir();
    let rig = write_rig(dir.path(), hw);
    let hw_file = collect(&rig, "hw", &dir.path().join("hw"));
    let sim_file = collect(&rig, "sim", &dir.path().join("sim"));

    let info = SessionInfo::read(&hw_file, ReadOptions::default()).expect("a readable session");
    assert_eq!(info.metadata["slidetrack.outcome"]["completed"], "true");
    assert_eq!(info.metadata["slidetrack"]["rig"], rig_name);
    let raw_channel = info.channels.iter().find(|c| c.topic == "/tactile/raw").expect("a raw channel");
    let layout =
        TaxelLayout::from_channel_metadata(&raw_channel.metadata).expect("a layout").expect("some layout");
    assert!(layout.device.starts_with("/dev/pts/"), "{}", layout.device);
    let grids: Vec<(String, u32, u32)> =
        layout.sensors.iter().map(|s| (s.name.clone(), s.rows, s.cols)).collect();
    assert_eq!(grids, ["thumb", "index", "middle"].map(|n| (n.to_string(), 4, 4)));

    let hw_raw = read_channel::<TactileRaw>(&hw_file, ReadOptions::default()).expect("raw scans");
    let sim_raw = read_channel::<TactileRaw>(&sim_file, ReadOptions::default()).expect("raw scans");
    let (n_hw, n_sim) = (hw_raw.len() as f64, sim_raw.len() as f64);
    assert!((n_hw - n_sim).abs() / n_sim < 0.1, "{n_hw} scans through the adapter, {n_sim} simulated");
    for (_, scan) in &hw_raw {
        let taxels: Vec<usize> = scan.sensors.iter().map(|s| s.taxels.len()).collect();
        assert_eq!(taxels, [16, 16, 16], "every taxel of every sensor in every scan");
    }
    // While the hand is open (zeroing) the data do not depend on timing:
    // the SLCAN lines carry exactly the simulated scans, taxel for taxel.
    // (CAN frames carry no scan counter: the sequence is the decoder's own.)
    for (k, ((_, a), (_, b))) in hw_raw.iter().zip(&sim_raw).take(45).enumerate() {
        assert_eq!(a.sensors, b.sensors, "scan {k}");
        assert_eq!(a.sequence, k as u64, "scans counted from 0, none lost");
    }
    let (_, last) = read_channel::<TactileDecoder>(&hw_file, ReadOptions::default())
        .expect("counters")
        .pop()
        .expect("some counters");
    assert_eq!((last.incomplete_scans, last.invalid_samples), (0, 0), "{last:?}");
    assert_eq!(last.frames, 48 * hw_raw.len() as u64, "one frame per taxel: {last:?}");
}

#[test]
fn collect_over_slcan_in_the_legacy_layout_records_every_taxel() {
    records_every_taxel_as_simulated(SLCAN_LEGACY, "emulated-slcan");
}

#[test]
fn collect_over_slcan_in_an_explicit_map_records_every_taxel() {
    records_every_taxel_as_simulated(SLCAN_MAP, "emulated-slcan-map");
}

#[test]
fn unplugging_the_adapter_mid_trial_releases_the_hand_and_keeps_the_data() {
    let dir = tempdir();
    let hw = SLCAN_LEGACY.replace("port = \"emulated\"", "port = \"emulated\", unplug_after_s = 2.5");
    let rig = write_rig(dir.path(), &hw);
    let out = dir.path().join("out");
    let output = slidetrack()
        .args(["-q", "collect", "--rig", "hw", "--config", &rig, "--duration", "20"])
        .args(["--no-camera", "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains("disconnected") && stderr.contains("/dev/pts/"), "{stderr}");
    assert!(stderr.contains("the hand was released") && stderr.contains("scans recorded so far"), "{stderr}");

    let file = out.join("box-s1-t000.mcap");
    assert_ended_by_disconnect(&file, 150..=260);
}

#[test]
fn a_tactile_id_that_the_hand_uses_is_one_line_naming_both_settings() {
    let dir = tempdir();
    let rig = dir.path().join("rig.toml");
    let text = "[hw.tactile]\nkind = \"can\"\ninterface = \"can3\"\n[[hw.tactile.map]]\nsensor = \"thumb\"\n\
                first_id = 0x2F8\n[[hw.tactile.map]]\nsensor = \"index\"\nfirst_id = 0x400\n\
                [[hw.tactile.map]]\nsensor = \"middle\"\nfirst_id = 0x500\n\
                [hw.hand]\nkind = \"can\"\ninterface = \"can3\"\n";
    std::fs::write(&rig, text).unwrap();
    let out = dir.path().join("out");
    let e = common::fails(&[
        "collect",
        "--rig",
        "hw",
        "--config",
        rig.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(
        e.contains("hw.tactile.map[0] (taxel 8) and hw.hand.setpoint_id both use CAN id 0x300 on can3"),
        "{e}"
    );
}
