//! A simulated 4x4 patch per fingertip: every taxel recorded, the contact
//! spread over the patch, the controller regulating each patch's mean z, and
//! a dEKF trained on whole-patch channels.

mod common;

use std::path::Path;

use common::{SIM_PATCH_4X4, collect, ok, tempdir};
use slidetrack_core::{FingerReading, Phase};
use slidetrack_session::{
    GraspControl, ReadOptions, SessionInfo, TactileRaw, TactileZeroed, TaxelLayout, read_channel,
};

fn patch_rig(dir: &Path) -> String {
    let path = dir.join("patch.toml");
    std::fs::write(&path, SIM_PATCH_4X4).expect("rig written");
    path.to_str().expect("utf-8 path").to_string()
}

/// RMS of desired - achieved per finger during the cycles (counts).
fn tracking_rms(file: &Path) -> f64 {
    let grasp = read_channel::<GraspControl>(file, ReadOptions::default()).expect("a readable session");
    let errors: Vec<f64> = grasp
        .iter()
        .filter(|(_, g)| g.phase == Phase::Cycles)
        .flat_map(|(_, g)| g.fingers.into_array().map(|f| f.desired - f.achieved))
        .collect();
    assert!(errors.len() > 100, "{} control ticks in the cycles", errors.len());
    (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt()
}

#[test]
fn a_patch_per_fingertip_records_every_taxel_and_the_grasp_still_follows_its_reference() {
    let dir = tempdir();
    let rig = patch_rig(dir.path());
    let (patch_dir, single_dir) = (dir.path().join("patch"), dir.path().join("single"));
    let file = collect(&patch_dir, "box", 2, 15.0, &["--no-camera", "--config", &rig]);
    let single = collect(&single_dir, "box", 2, 15.0, &["--no-camera"]);

    let info = SessionInfo::read(&file, ReadOptions::default()).unwrap();
    assert_eq!(info.metadata["slidetrack.outcome"]["completed"], "true");
    let channel = info.channel("/tactile/raw").unwrap();
    let layout = TaxelLayout::from_channel_metadata(&channel.metadata).unwrap().unwrap();
    assert_eq!(layout.sensors.iter().map(|s| s.rows * s.cols).collect::<Vec<_>>(), [16, 16, 16]);
    assert_eq!(layout.fingers.index, FingerReading::mean("index"));
    let in_session = TaxelLayout::from_channel_metadata(&info.metadata["slidetrack"]).unwrap().unwrap();
    assert_eq!(in_session, layout, "the session metadata holds the layout too");

    // Every taxel of every patch, every scan.
    let raw = read_channel::<TactileRaw>(&file, ReadOptions::default()).unwrap();
    assert!(raw.iter().all(|(_, r)| r.sensors.iter().map(|s| s.taxels.len()).sum::<usize>() == 48));

    // The contact is spread over the patch: the four centre taxels feel more
    // than the four corners while the hand squeezes.
    let zeroed = read_channel::<TactileZeroed>(&file, ReadOptions::default()).unwrap();
    let squeezed = &zeroed[zeroed.len() / 2..];
    let mean_z = |taxels: [usize; 4]| {
        let n = (squeezed.len() * 4) as f64;
        squeezed
            .iter()
            .map(|(_, z)| taxels.iter().map(|&t| z.sensors[0].taxels[t].z).sum::<f64>())
            .sum::<f64>()
            / n
    };
    let (centre, corners) = (mean_z([5, 6, 9, 10]), mean_z([0, 3, 12, 15]));
    assert!(centre > 1.5 * corners && corners > 0.0, "centre {centre} counts, corners {corners}");

    // Each finger's reading is its patch mean, which feels what the single
    // module feels: the controller tracks its reference about as well.
    let (patch_rms, single_rms) = (tracking_rms(&file), tracking_rms(&single));
    eprintln!("grasp tracking RMS: patch means {patch_rms:.1} counts, single modules {single_rms:.1}");
    assert!(patch_rms < 2.0 * single_rms + 20.0, "patch {patch_rms} vs single {single_rms}");
}

#[test]
fn a_dekf_trains_on_whole_patch_channels_and_records_them_in_the_model() {
    let dir = tempdir();
    let rig = patch_rig(dir.path());
    let sessions: Vec<_> = (1..=3)
        .map(|seed| collect(dir.path(), "box", seed, 20.0, &["--no-camera", "--config", &rig]))
        .collect();
    let model = dir.path().join("patch.safetensors");
    let files: Vec<&str> = sessions.iter().map(|p| p.to_str().unwrap()).collect();
    // The z of the four centre taxels of the thumb's patch and the index's patch mean.
    let channels = "thumb.5.z,thumb.6.z,thumb.9.z,thumb.10.z,index.mean.x,index.mean.y";
    let mut args = vec!["-q", "train"];
    args.extend(&files);
    args.extend([
        "--channels",
        channels,
        "--truth",
        "sim",
        "--schedule",
        "2:1",
        "--json",
        "--out",
        model.to_str().unwrap(),
    ]);
    let trained: serde_json::Value = serde_json::from_str(&ok(&args)).unwrap();
    let names: Vec<&str> =
        trained["channels"].as_array().unwrap().iter().map(|c| c.as_str().unwrap()).collect();
    assert_eq!(names.join(","), channels, "the model records its channels");
    let text = ok(&["-q", "eval", files[0], "--model", model.to_str().unwrap(), "--truth", "sim", "--json"]);
    let report: serde_json::Value = serde_json::from_str(&text).unwrap();
    // A 2-epoch model need not be good: it must run on the patch channels.
    assert!(report["position_rmse_cm"].as_f64().is_some_and(f64::is_finite), "{report}");
    assert_eq!(report["steps"], 788, "{report}");
}
