#!/usr/bin/env bash
# The measurements that need a real GPU, in one command: the device, per-pass GPU
# timings, and the equal-time studies of both papers (error against a converged
# reference versus GPU milliseconds, several seeds with their spread).
#
#   tools/gpu-check.sh [--quick] [--no-tests] [OUT_DIR]
#
# OUT_DIR (default gpu-check-<date>) receives devices.txt, tests.txt (the whole test
# suite on this machine's default device, validation layers on), profile-*.txt, one
# study-*/ folder per study (study.csv, study.md, study.png) and summary.md, which
# collects the equal-time ratios of every study. --quick shrinks images, frames and
# references so that the whole run fits a few minutes on lavapipe (a smoke test of
# the script, not a measurement).
#
# On a lent GPU machine (see docs/restir.md "Measuring on a GPU"): unpack the Vulkan
# loader there first, then run this script from the repository root. It builds the
# release binary if needed. Set NIMBUS_DEVICE=<name substring> to pick a device.
set -euo pipefail

quick=0
tests=1
while [[ "${1:-}" == --* ]]; do
    case "$1" in
        --quick) quick=1 ;;
        --no-tests) tests=0 ;;
        *) echo "unknown option $1" >&2; exit 2 ;;
    esac
    shift
done
out="${1:-gpu-check-$(date +%Y%m%d-%H%M%S)}"
mkdir -p "$out"
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"

if [[ -z "${NIMBUS_BIN:-}" ]]; then
    cargo build --release --quiet
    NIMBUS_BIN="$root/target/release/nimbus"
fi
nimbus() { "$NIMBUS_BIN" "$@"; }

# Sizes: the papers' studies on a GPU, a smoke test on lavapipe.
if ((quick)); then
    size=(--width 48 --height 36)
    hd=(--width 64 --height 36)
    frames=2
    ref=(--reference-frames 8 --reference-spp 4)
    seeds=2
    frames_list=1,4
    box_samples=1,4
    bounces_list=1
    spp_list=1,2
else
    size=(--width 640 --height 480)
    hd=(--width 1920 --height 1080)
    frames=16
    ref=(--reference-frames 1024 --reference-spp 16)
    seeds=3
    frames_list=1,2,4,8,16,32,64
    box_samples=1,2,4,8,16,32
    bounces_list="1 3 7"
    spp_list=1,2,4,8,16,32
fi
cache=(--cache-dir "$out/references")

nimbus devices | tee "$out/devices.txt"

# The test suite on this device (goldens, statistical tests, validation layers).
if ((tests)); then
    if cargo test --release >"$out/tests.txt" 2>&1; then
        echo "tests passed" | tee -a "$out/tests.txt"
    else
        echo "tests FAILED (see $out/tests.txt)"
    fi
fi

# Per-pass GPU timings (timestamp queries): the shipped scenes, and ReSTIR at 1920x1080
# with K = 1 and 3.
for scene in cloud-restir box-sphere window; do
    nimbus profile "assets/scenes/$scene.toml" "${size[@]}" --frames "$frames" \
        >"$out/profile-$scene.txt" 2>&1 || echo "profile $scene failed (see $out/profile-$scene.txt)"
done
for k in 1 3; do
    nimbus profile assets/scenes/cloud-restir.toml "${hd[@]}" --frames "$frames" \
        --set "integrator.max_bounces=$k" >"$out/profile-cloud-restir-hd-k$k.txt" 2>&1 ||
        echo "profile K=$k failed (see $out/profile-cloud-restir-hd-k$k.txt)"
done

# Volumetric ReSTIR against its equal-time baseline (decomposition + residual ratio
# tracking), per bounce count: the error of the mean over F frames against the total
# GPU time (F is the knob; ReSTIR draws one path per pixel per frame), for the paper's
# algorithm and the levers beyond it (pairwise MIS, pre-spatial history, sigma* floor;
# the baseline ignores them and renders once).
for k in $bounces_list; do
    nimbus study assets/scenes/cloud-restir-study.toml "${size[@]}" "${ref[@]}" "${cache[@]}" \
        --seeds "$seeds" --warmup 16 \
        --vary "max_bounces=$k" --vary volume=baseline,restir --vary "frames=$frames_list" \
        --vary mis=talbot,pairwise --vary temporal_history=spatial,temporal \
        --vary sigma_star_floor=0,0.25 --baseline volume=baseline \
        --out-dir "$out/study-restir-k$k"
done

# The benchmark scenes (assets/scenes/bench: 256x160x256 cumulus with g = 0 and 0.8,
# an HDR sky with a small sun, emissive explosions with matched and mismatched
# colours) at 320x240, ReSTIR with the paper's defaults against the baseline.
[[ -f target/bench/sky-sun.exr ]] || cargo run --release --quiet --example make_sky -- target/bench/sky-sun.exr
if ((quick)); then
    bench=(cloud-g08)
    bench_size=("${size[@]}")
else
    bench=(cloud-g0 cloud-g08 sky-sun explosion-matched explosion-mismatched)
    bench_size=() # the scenes' own 320x240
fi
for scene in "${bench[@]}"; do
    for k in $bounces_list; do
        nimbus study "assets/scenes/bench/$scene.toml" "${bench_size[@]}" "${ref[@]}" "${cache[@]}" \
            --seeds "$seeds" --warmup 16 \
            --vary "max_bounces=$k" --vary volume=baseline,restir --vary "frames=$frames_list" \
            --baseline volume=baseline \
            --out-dir "$out/study-bench-$scene-k$k"
        # The paper's metric (issue 15's "done means"): each frame's own error at steady
        # state, ReSTIR against the baseline with its spp raised to ReSTIR's frame time
        # (ReSTIR's spp > 1 rows are left out by the study), with and without spatial
        # reuse.
        nimbus study "assets/scenes/bench/$scene.toml" "${bench_size[@]}" "${ref[@]}" "${cache[@]}" \
            --seeds "$seeds" --per-frame --frames "$frames" \
            --vary "max_bounces=$k" --vary volume=baseline,restir --vary spatial_neighbors=3,0 \
            --vary "spp=$spp_list" --baseline volume=baseline \
            --out-dir "$out/study-bench-per-frame-$scene-k$k"
    done
done

# The box-medium paper's estimators at equal time (RM is the baseline of the ratios),
# ME (moment-based, approximate) beside them: its error floor where its heuristic holds
# (me-detached) and where it fails (me-interleaved, box-sphere).
for scene in box-sphere window me-detached me-interleaved; do
    nimbus study "assets/scenes/$scene.toml" "${size[@]}" "${ref[@]}" "${cache[@]}" \
        --seeds "$seeds" --frames "$frames" \
        --vary box_estimator=mcwvds,reds,rees,rm,mcds,me --vary "box_samples=$box_samples" \
        --baseline box_estimator=rm \
        --out-dir "$out/study-$scene"
done

# One page with every study's equal-time section.
{
    echo "# gpu-check $(date -u +%Y-%m-%dT%H:%M:%SZ)"
    echo
    echo '```'
    cat "$out/devices.txt"
    echo '```'
    for dir in "$out"/study-*/; do
        echo
        echo "## $(basename "$dir")"
        echo
        sed -n '/^## /,$p' "$dir/study.md" | grep -v '^!\[' || true
    done
} >"$out/summary.md"
echo "wrote $out/summary.md"
