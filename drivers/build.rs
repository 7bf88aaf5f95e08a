//! Turns the environment variables that name test devices into cfg flags,
//! so that device tests are `#[ignore]`d unless a device is named:
//! `SLIDETRACK_VCAN=vcan0` enables `slidetrack_vcan`, `SLIDETRACK_V4L2=/dev/video0`
//! enables `slidetrack_v4l2`, `SLIDETRACK_RGBD_DEPTH=/dev/video0` (with
//! `SLIDETRACK_RGBD_COLOR`) enables `slidetrack_rgbd`. Nothing here looks for or needs a device.

fn main() {
    for (var, flag) in [
        ("SLIDETRACK_VCAN", "slidetrack_vcan"),
        ("SLIDETRACK_V4L2", "slidetrack_v4l2"),
        ("SLIDETRACK_RGBD_DEPTH", "slidetrack_rgbd"),
    ] {
        println!("cargo::rerun-if-env-changed={var}");
        println!("cargo::rustc-check-cfg=cfg({flag})");
        if std::env::var_os(var).is_some_and(|v| !v.is_empty()) {
            println!("cargo::rustc-cfg={flag}");
        }
    }
}
