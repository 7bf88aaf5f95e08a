#!/usr/bin/env bash
# Installs what slidetrack needs on Debian or Ubuntu, only what is missing:
#   - OpenCV 4 development files with the contrib modules (ArUco) and
#     clang/libclang, which the opencv crate needs to generate its bindings;
#   - zstd's development files (libzstd-dev, found with pkg-config), which
#     the sessions' MCAP chunk compression links;
#   - libjpeg-turbo's TurboJPEG (libturbojpeg0-dev, found with pkg-config),
#     which reads and writes JPEG images;
#   - a TrueType font (DejaVu) for the text of plots;
#   - the kernel's user-space headers (linux/videodev2.h), from which the v4l
#     crate generates its V4L2 bindings with libclang;
#   - with --test (or --test-node): Node.js and npm (Debian's packages, when
#     no `node` is installed) and the official Foxglove WebSocket client
#     (@foxglove/ws-protocol, with ws), pinned by tests/node/package-lock.json,
#     in target/node/node_modules, for the live view's open-protocol test;
#   - with --test: a Python virtual environment (target/pyenv) holding the
#     official MCAP reader and NumPy, minimalmodbus with pyserial (an
#     independent Modbus RTU client for the emulated Robotiq gripper) and
#     websockets (the independent Foxglove WebSocket client of the live
#     view's tests), used by the interoperability tests, OpenCV's Python
#     bindings (opencv-python-headless: the independent board poses of
#     calibration/tests/board_python.rs), and PyTorch (the
#     dEKF's PyTorch twin, scripts/dekf_torch_train.py, checked against the
#     golden file by tests/dekf_golden.rs; from PyPI, about 5 GB, on CPU),
#     rosbags (the independent ROS 2 bag reader of tests/ros2_bag.rs) and
#     cyclonedds (Eclipse Cyclone DDS, the independent DDS of tests/ros2_live.rs;
#     its wheel bundles the C library), all installed by uv (Astral's
#     installer, itself from PyPI).
# Runs apt-get through sudo only when not root. `--test` is `--test-system`
# (the system packages, python3-venv included) followed by `--test-python`
# (target/pyenv); scripts/test runs the second while the workspace compiles.
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(libopencv-dev libopencv-contrib-dev clang libclang-dev pkg-config libzstd-dev libturbojpeg0-dev fonts-dejavu-core linux-libc-dev)
mode="${1:-}"
system=1
python=0
node=0
case "$mode" in
  "") ;;
  --test) python=1 node=1 ;;
  --test-system) ;;
  --test-python) system=0 python=1 ;;
  --test-node) system=0 node=1 ;;
  *) echo "setup: unknown option $mode (use --test, --test-system, --test-python or --test-node)" >&2; exit 2 ;;
esac

if [ "$mode" != "" ]; then
  python3 -c 'import venv, ensurepip' 2>/dev/null || packages+=(python3-venv)
fi

missing=()
[ "$system" = 1 ] || packages=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# Installs Debian packages "$@" (through sudo only when not root).
apt_install() {
  if ! command -v apt-get >/dev/null; then
    echo "setup: missing $* and no apt-get here; install them with your package manager" >&2
    exit 1
  fi
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  echo "setup: installing $*" >&2
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "$@" >/dev/null
}
if [ "${#missing[@]}" -gt 0 ]; then
  apt_install "${missing[@]}"
fi

# --- begin: Node.js and the Foxglove WebSocket client (--test, --test-node) ---
# Debian's nodejs and npm when there is no `node`, then the packages pinned by
# tests/node/package-lock.json into target/node (`npm ci`), again whenever the
# lock file changes. tests/live.rs finds them there.
if [ "$node" = 1 ]; then
  if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
    apt_install nodejs npm
  fi
  if ! cmp -s tests/node/package-lock.json target/node/package-lock.json \
    || [ ! -f target/node/node_modules/@foxglove/ws-protocol/package.json ]; then
    echo "setup: installing @foxglove/ws-protocol into target/node" >&2
    mkdir -p target/node
    cp tests/node/package.json tests/node/package-lock.json target/node/
    npm ci --prefix target/node --no-audit --no-fund --loglevel=error
  fi
fi
# --- end: Node.js and the Foxglove WebSocket client ---

if [ "$python" = 1 ]; then
  # The pinned packages (what each is for: the header above), and the
  # modules whose import shows they are all there.
  python_packages=('mcap==1.6.0' 'numpy==2.4.6' 'minimalmodbus==2.1.1' 'pyserial==3.5' 'websockets==15.0.1'
    'opencv-python-headless==4.13.0.92' 'torch==2.15.0' 'rosbags==0.11.9' 'cyclonedds==11.0.1')
  python_modules='mcap, numpy, minimalmodbus, serial, websockets, cv2, torch, rosbags, cyclonedds.domain'
  if [ ! -x target/pyenv/bin/python ]; then
    echo "setup: creating target/pyenv" >&2
    mkdir -p target
    python3 -m venv target/pyenv
  fi
  if ! target/pyenv/bin/python -c "import $python_modules" 2>/dev/null; then
    # uv installs them: it downloads and unpacks in parallel, does not
    # byte-compile every module up front, and links files from its cache
    # (~/.cache/uv) where pip copies them. The whole set (about 5.6 GB,
    # PyTorch's CUDA libraries included) took 25 s and 42 s of CPU from an
    # empty cache against pip's 143 s and 138 s of CPU, and 1.5 s from a
    # full one (issue 29; the tests install it while the workspace compiles).
    if [ ! -x target/pyenv/bin/uv ]; then
      target/pyenv/bin/python -m pip install -q 'uv==0.13.9'
    fi
    echo "setup: installing ${python_packages[*]} into target/pyenv" >&2
    target/pyenv/bin/uv pip install -q --python target/pyenv/bin/python "${python_packages[@]}"
  fi
fi
