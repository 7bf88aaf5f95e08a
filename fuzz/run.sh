#!/usr/bin/env bash
# Fuzzes the tactile decoders and the session reader for a bounded time: every target in
# fuzz_targets/ for SECONDS (default 60) each. Needs a nightly toolchain
# (`rustup toolchain install nightly`), not cargo-fuzz: it builds the targets
# with the coverage flags cargo-fuzz uses and runs libFuzzer directly.
# Crashing inputs land in fuzz/artifacts/, the corpus grows in fuzz/corpus/.
# The SLCAN adapter decoder (slcan_decoder) is fuzzed with the others.
# The xela_server WebSocket JSON decoder (xela_ws_decoder) is fuzzed with the others.
# The Robotiq Modbus RTU codec (modbus_rtu) is fuzzed with the others.
#   fuzz/run.sh [SECONDS]
set -euo pipefail
cd "$(dirname "$0")"
seconds="${1:-60}"
host="$(rustc +nightly -vV | sed -n 's/^host: //p')"
export RUSTFLAGS="-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares --cfg fuzzing -Cdebug-assertions"
cargo +nightly build --release --target "$host" --bins
bin_dir="${CARGO_TARGET_DIR:-target}/$host/release"
mkdir -p artifacts
for source in fuzz_targets/*.rs; do
    name="$(basename "$source" .rs)"
    mkdir -p "corpus/$name"
    echo "fuzzing $name for $seconds s"
    "$bin_dir/$name" -max_total_time="$seconds" -rss_limit_mb=1024 -print_final_stats=1 \
        -artifact_prefix=artifacts/ "corpus/$name"
done
