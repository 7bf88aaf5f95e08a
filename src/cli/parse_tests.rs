//! Tests that the documented command lines of `slip` and `vision` parse
//! (beside the argument types, so that those never import the parser).

use std::path::PathBuf;

use clap::Parser;

use super::*;

#[test]
fn slip_takes_files_and_json() {
    let cli = Cli::try_parse_from(["slidetrack", "slip", "a.mcap", "dir", "--json"]).unwrap();
    let Command::Slip(a) = cli.command else { panic!("not slip") };
    assert_eq!(a.files, [PathBuf::from("a.mcap"), PathBuf::from("dir")]);
    assert!(a.json);
    assert!(Cli::try_parse_from(["slidetrack", "slip"]).is_err(), "a file is required");
}

#[test]
fn the_documented_commands_parse() {
    let cli = Cli::try_parse_from([
        "slidetrack",
        "vision",
        "track",
        "--tracker",
        "roft",
        "--input",
        "s.mcap",
        "--model",
        "sim",
        "--out",
        "e.mcap",
    ])
    .unwrap();
    let Command::Vision(VisionArgs { command: VisionCommand::Track(t) }) = cli.command else { panic!() };
    assert_eq!(t.tracker, TrackerArg::Roft);
    assert_eq!(t.measurements, MeasurementsArg::Input);
    let live = ["slidetrack", "vision", "track", "--tracker", "roft", "--model", "m.obj", "--live"];
    let cli = Cli::try_parse_from(live.iter().chain(&["--rig", "r.toml", "--duration", "5"])).unwrap();
    let Command::Vision(VisionArgs { command: VisionCommand::Track(t) }) = cli.command else { panic!() };
    assert!(t.live && t.input.is_none() && t.duration == Some(5.0));
    assert!(Cli::try_parse_from(live).is_err(), "--live needs --rig");
    assert!(Cli::try_parse_from(live.iter().chain(&["--rig", "r", "--input", "s.mcap"])).is_err());
    let cli = Cli::try_parse_from([
        "slidetrack",
        "vision",
        "eval",
        "--ablation",
        "--json",
        "--objects",
        "soup_can,cracker_box",
    ])
    .unwrap();
    let Command::Vision(VisionArgs { command: VisionCommand::Eval(e) }) = cli.command else { panic!() };
    assert!(e.ablation && e.json);
    assert_eq!(e.objects, vec!["soup_can", "cracker_box"]);
    assert!(
        Cli::try_parse_from([
            "slidetrack",
            "vision",
            "track",
            "--tracker",
            "other",
            "--input",
            "x",
            "--model",
            "m"
        ])
        .is_err()
    );
}

#[test]
fn the_source_options_parse() {
    let cli = Cli::try_parse_from([
        "slidetrack",
        "vision",
        "track",
        "--tracker",
        "roft",
        "--input",
        "s.mcap",
        "--model",
        "sim",
        "--measurements",
        "external",
        "--listen",
        "127.0.0.1:9000",
        "--external-wait-ms",
        "0",
    ])
    .unwrap();
    let Command::Vision(VisionArgs { command: VisionCommand::Track(t) }) = cli.command else { panic!() };
    assert_eq!(
        (t.measurements, t.external.listen.as_str(), t.external.external_wait_ms),
        (MeasurementsArg::External, "127.0.0.1:9000", 0)
    );
    let aruco = [
        "slidetrack",
        "vision",
        "track",
        "--tracker",
        "roft",
        "--input",
        "s",
        "--model",
        "m",
        "--measurements",
        "aruco",
    ];
    assert!(Cli::try_parse_from(aruco).is_err(), "aruco without --aruco-config");
    let cli = Cli::try_parse_from(aruco.iter().copied().chain(["--aruco-config", "a.toml"])).unwrap();
    let Command::Vision(VisionArgs { command: VisionCommand::Track(t) }) = cli.command else { panic!() };
    assert_eq!(t.aruco_config.as_deref(), Some(std::path::Path::new("a.toml")));
}
