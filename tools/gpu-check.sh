#!/usr/bin/env bash
# The measurements that need a real GPU, in one command: the device, per-pass GPU
# timings, and the equal-time studies of both papers (error against a converged
# reference versus GPU milliseconds, several seeds with their spread).
#
#   tools/gpu-check.sh [--quick | --lent | --motion | --gallery | --baseline-ab] [--no-tests] [OUT_DIR]
#
# OUT_DIR (default gpu-check-<date>) receives devices.txt, tests.txt (the whole test
# suite on this machine's default device, validation layers on), profile-*.txt, one
# study-*/ folder per study (study.csv, study.md, study.png), steps.txt (what each step
# took) and summary.md, which collects the equal-time ratios of every study.
#
# Every mode first runs `nimbus bench` (bench.txt, bench.json: ms and work per sample of
# the benchmark cases beside assets/bench/baseline.json; docs/performance.md), and
# (outside --gallery and --baseline-ab) times the driver's pipeline builds from stripped and
# whole shader modules (pipelines-stripped.txt, pipelines-whole.txt).
#
# --lent sizes the run for one command of a lent GPU machine (about 8 minutes on an H200;
# see docs/restir.md "Measuring on a GPU" for the steps): no test suite; `nimbus bench`;
# the benchmark cloud's per-pass profiles at 1920x1080 (ReSTIR and the 1-spp baseline,
# K = 1 and 3, ReSTIR's work counters at K = 3); issue 15's per-frame equal-time studies
# of ReSTIR against the baseline on the benchmark clouds (g = 0 and 0.8, 3 seeds, at
# 960x540, since the benchmark's 320x240 leaves a GPU idle) at K = 3 and 1, then the
# moving camera at K = 3, then the clouds at K = 7 (what a cut run loses first). Every
# timed render settles the GPU first (--settle-ms); a study.md that ends in a WARNING
# mixed device states and is no measurement (NIMBUS_LENT_SMOKE=1: the same steps at
# lavapipe sizes, to test the script). --quick shrinks the full run into a
# lavapipe smoke test of the script (a few minutes on 2 cores): a test of the script,
# not a measurement.
#
# --motion sizes issue 26's motion studies for one lent-machine command (about 9 minutes
# on an H200): the per-frame equal-time studies at 960x540 of the motion benchmarks
# (assets/scenes/bench/motion) not measured yet, most wanted first: the rotating HDR sky,
# the explosions under the orbiting camera with emission separate and folded (the
# mismatched one also with the target's luminance and sum), the moving
# camera at K = 7, the animated plume (written first by the make_plume example: set
# NIMBUS_MAKE_PLUME to its binary, target/release/examples/make_plume by default; at K = 3
# with spatial reuse on its density's frames and without), the
# moving sun at K = 1 and 7; last, the moving camera under the optical-depth shifts
# (camera-g0-k3-tau-shift, camera-g0-k3-spatial-shift). Each study is cut at its own time
# limit so that a slow one leaves the others their time; steps.txt says which finished.
#
# --gallery renders docs/gallery.md's scenes at 1920x1080 (gallery/NAME.png, NAME.log
# with the render's GPU time) and profiles each at 1080p (gallery/profile-NAME.txt: median
# ms per frame and pass), times the GPU denoiser on a 1080p frame of each grid
# integrator, and runs the per-frame equal-time study (ReSTIR against the baseline at
# 960x540, 3 seeds) on the cumulus, the explosion and the smoke (issue 27). The explosion and
# the smoke are written first by the make_explosion and make_smoke examples (set
# NIMBUS_MAKE_EXPLOSION / NIMBUS_MAKE_SMOKE to their binaries; by default
# target/release/examples/). About 6 minutes on an H200; NIMBUS_GALLERY_SMOKE=1 shrinks
# it into a lavapipe test of the script; NIMBUS_GALLERY_ONLY="NAME ..." runs only the
# named pictures (cumulus-baseline, smoke-fog, ...), `denoise` and `study-cumulus` /
# `study-explosion` / `study-smoke`.
#
# --baseline-ab (about 2 minutes on an H200; run it first in a lent session) checks that
# timings of the baseline's light frames are taken in one state of the GPU: on 2026-11-28
# it showed that the 12.3 ms measured at ac4f19f against 2.17 ms at d97c1f1 was the H200's
# idle clock, not the code (docs/performance.md, "GPU timings and the device's clocks"),
# and every timed render now settles the GPU first (--settle-ms); round 1 must now agree
# with round 2. It runs the baseline at K = 1
# and 3 with nee = auto (split, the sky along the path) against nee = one (both compiled
# out) and with the density from the buffer, at 1920x1080 and 960x540, twice in
# alternation (a state of the machine shows as a change between rounds, code as a change
# between configurations), each frame's ms in order, the longest invocation's counters,
# and the GPU's clocks sampled by nvidia-smi throughout (clocks.csv) where it exists.
# NIMBUS_AB_OLD=<an older nimbus binary> (say f012198's, built with `git worktree add
# /tmp/old f012198 && cargo build --release` there, and carried) adds its 1-spp frame to
# every round, with the scene's own settings. NIMBUS_AB_SMOKE=1 shrinks it into a
# lavapipe test of the script.
#
# NIMBUS_MOTION_HD=1 makes --motion the 1080p run issue 26 asks for (about 5 minutes on
# an H200): the motion benchmarks' per-frame profiles at 1920x1080 (K = 1 and 3, ReSTIR
# and the 1-spp baseline) and the moving camera's equal-time study at 1080p (2 seeds).
#
# The release binary is built when NIMBUS_BIN is unset; on a lent machine, carry one
# built here and set NIMBUS_BIN. Set NIMBUS_DEVICE=<name substring> to pick a device.
set -euo pipefail

mode=full
tests=1
while [[ "${1:-}" == --* ]]; do
    case "$1" in
        --quick) mode=quick ;;
        --lent) mode=lent; tests=0 ;;
        --motion) mode=motion; tests=0 ;;
        --gallery) mode=gallery; tests=0 ;;
        --baseline-ab) mode=ab; tests=0 ;;
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
    # Both binaries: `nimbus study` runs target/release/nimbus-study (crates/nimbus-study).
    cargo build --release --quiet
    NIMBUS_BIN="$root/target/release/nimbus"
fi
nimbus() { "$NIMBUS_BIN" "$@"; }

# Runs "$@" as step NAME, logging its wall time (and a failure, without stopping the run).
step() {
    local name=$1
    shift
    local start=$SECONDS
    if "$@"; then
        echo "$name: $((SECONDS - start)) s" | tee -a "$out/steps.txt"
    else
        echo "$name: FAILED after $((SECONDS - start)) s" | tee -a "$out/steps.txt"
    fi
}

# Sizes: the papers' studies on a GPU, a smoke test on lavapipe.
case $mode in
    quick)
        size=(--width 48 --height 36)
        hd=(--width 64 --height 36)
        frames=2
        ref=(--reference-frames 8 --reference-spp 4)
        seeds=2
        frames_list=1,4
        box_samples=1,4
        bounces_list=1
        spp_list=1,2
        ;;
    lent)
        size=(--width 640 --height 480)
        hd=(--width 1920 --height 1080)
        frames=16
        ref=(--reference-frames 64 --reference-spp 16)
        seeds=3
        frames_list=1,4,16
        box_samples=1,4,16
        # K = 7 after the moving camera (below): the cut of a slow run falls on it.
        bounces_list="3 1"
        spp_list=1,2,4,8,16,32
        ;;
    full | gallery | ab)
        size=(--width 640 --height 480)
        hd=(--width 1920 --height 1080)
        frames=16
        ref=(--reference-frames 1024 --reference-spp 16)
        seeds=3
        frames_list=1,2,4,8,16,32,64
        box_samples=1,2,4,8,16,32
        bounces_list="1 3 7"
        spp_list=1,2,4,8,16,32
        ;;
esac
# NIMBUS_LENT_SMOKE=1 runs --lent's steps at --quick's sizes: a lavapipe test of the
# script before it spends a lent machine's minutes.
lent_study_size=(--width 960 --height 540)
if [[ $mode == lent && -n ${NIMBUS_LENT_SMOKE:-} ]]; then
    hd=(--width 64 --height 36)
    frames=2
    ref=(--reference-frames 8 --reference-spp 4)
    seeds=1
    spp_list=1,2
    lent_study_size=(--width 48 --height 36)
fi
cache=(--cache-dir "$out/references")

nimbus devices | tee "$out/devices.txt"

if [[ $mode == ab ]]; then
    if command -v nvidia-smi >/dev/null; then
        nvidia-smi --query-gpu=timestamp,clocks.sm,clocks.mem,clocks.max.sm,power.draw,temperature.gpu,utilization.gpu,clocks_throttle_reasons.active \
            --format=csv -lms 200 >"$out/clocks.csv" 2>&1 &
        smi=$!
        trap 'kill $smi 2>/dev/null || true' EXIT
    fi
    ab_sizes=("1920 1080" "960 540")
    ab_frames=(--frames 16 --warmup 4)
    if [[ -n ${NIMBUS_AB_SMOKE:-} ]]; then
        ab_sizes=("48 27" "32 18")
        ab_frames=(--frames 2 --warmup 1)
    fi
    c=assets/scenes/bench/cloud-g0.toml
    # NAME ARGS...: one baseline profile of the benchmark cloud, cut after 60 s.
    ab_bin=$NIMBUS_BIN
    ab_profile() {
        local name=$1
        shift
        step "profile $name" timeout 60 "$ab_bin" profile "$c" "${ab_frames[@]}" \
            --set integrator.volume=baseline "$@" >"$out/profile-$name.txt" 2>&1
    }
    for round in 1 2; do
        for wh in "${ab_sizes[@]}"; do
            read -r w h <<<"$wh"
            for k in 3 1; do
                for nee in auto one; do
                    ab_profile "r$round-${w}x$h-k$k-$nee" --width "$w" --height "$h" \
                        --set "integrator.max_bounces=$k" --set "integrator.baseline.nee=\"$nee\""
                done
                if [[ -n ${NIMBUS_AB_OLD:-} ]]; then
                    ab_bin=$NIMBUS_AB_OLD
                    ab_profile "r$round-${w}x$h-k$k-old" --width "$w" --height "$h" --set "integrator.max_bounces=$k"
                    ab_bin=$NIMBUS_BIN
                fi
            done
        done
    done
    read -r w h <<<"${ab_sizes[0]}"
    for nee in auto one; do
        ab_profile "counters-${w}x$h-k3-$nee" --width "$w" --height "$h" --counters \
            --set integrator.max_bounces=3 --set "integrator.baseline.nee=\"$nee\""
    done
    ab_profile "${w}x$h-k3-auto-buffer" --width "$w" --height "$h" --set integrator.max_bounces=3 \
        --set 'integrator.baseline.density_fetch="buffer"'
    step bench "$NIMBUS_BIN" bench --baseline "$root/assets/bench/baseline.json" --json "$out/bench.json" \
        >"$out/bench.txt" 2>&1
    # One line per profile: median, min and max frame ms, and the frames in order.
    for f in "$out"/profile-*.txt; do
        printf '%-44s %s\n' "$(basename "$f" .txt)" \
            "$(awk '$1 == "frame" && $2 != "ms" {print $2, $3, $4} /^frame ms in order:/ {sub(/^frame ms in order: /, ""); print "|", $0}' "$f" | tr '\n' ' ')"
    done | tee "$out/summary.txt"
    echo "wrote $out"
    exit 0
fi

if [[ $mode == motion ]]; then
    [[ -f target/bench/sky-sun.exr ]] || nimbus make-sky target/bench/sky-sun.exr
    plume_bin="${NIMBUS_MAKE_PLUME:-$root/target/release/examples/make_plume}"
    # NIMBUS_MOTION_SMOKE=1 shrinks it into a test of this script on lavapipe.
    if [[ -n ${NIMBUS_MOTION_SMOKE:-} ]]; then
        motion_size=(--width 32 --height 24 --frames 2 --seeds 1 --reference-frames 2 --reference-spp 1)
    elif [[ -n ${NIMBUS_MOTION_HD:-} ]]; then
        motion_size=(--width 1920 --height 1080 --frames 8 --seeds 2 --reference-frames 16 --reference-spp 16)
    else
        motion_size=(--width 960 --height 540 --frames 8 --seeds 3 --reference-frames 32 --reference-spp 16)
    fi
    motion_common=("${motion_size[@]}" --per-frame --cache-dir "$out/references"
        --vary volume=baseline,restir --vary spp=1,2,4,8,16,32 --baseline volume=baseline)
    # NAME SECONDS SCENE K [--vary ...]: one study, cut after SECONDS (only the names in
    # NIMBUS_MOTION_ONLY where that is set).
    motion_study() {
        local name=$1 limit=$2 scene=$3 k=$4
        shift 4
        if [[ -n ${NIMBUS_MOTION_ONLY:-} && " $NIMBUS_MOTION_ONLY " != *" $name "* ]]; then
            return 0
        fi
        step "study $name" timeout "$limit" "$NIMBUS_BIN" study "$scene" "${motion_common[@]}" \
            --vary "max_bounces=$k" "$@" --out-dir "$out/study-$name" >"$out/study-$name.log" 2>&1
    }
    m=assets/scenes/bench/motion
    if [[ -n ${NIMBUS_MOTION_HD:-} ]]; then
        # The paper's marks are ms per 1080p frame (55 at K = 1, 142 at K = 3 on an RTX
        # 3090): each motion benchmark's frame at 1080p, K = 1 and 3, by ReSTIR and by
        # the 1-spp baseline, then the equal-time study of the moving camera at 1080p.
        hd_size=(--width 1920 --height 1080)
        [[ -n ${NIMBUS_MOTION_SMOKE:-} ]] && hd_size=(--width 32 --height 24)
        for scene in camera-g0 sun-g0 sky-g06 explosion-matched; do
            for k in 1 3; do
                step "profile $scene k$k" timeout 60 "$NIMBUS_BIN" profile "$m/$scene.toml" \
                    "${hd_size[@]}" --frames 8 --warmup 4 --set "integrator.max_bounces=$k" \
                    >"$out/profile-$scene-hd-k$k.txt" 2>&1
                step "profile $scene baseline k$k" timeout 60 "$NIMBUS_BIN" profile "$m/$scene.toml" \
                    "${hd_size[@]}" --frames 8 --warmup 4 --set "integrator.max_bounces=$k" \
                    --set integrator.volume=baseline >"$out/profile-$scene-baseline-hd-k$k.txt" 2>&1
            done
        done
        motion_study camera-g0-hd-k1 200 $m/camera-g0.toml 1
        rm -rf "$out/references"
        echo "wrote $out"
        exit 0
    fi
    motion_study sky-g06-k3 100 $m/sky-g06.toml 3 --vary env_reuse=map,world
    motion_study explosion-mismatched-k3 150 $m/explosion-mismatched.toml 3 --vary emission=separate,folded \
        --vary target=luminance,sum
    motion_study explosion-matched-k3 110 $m/explosion-matched.toml 3 --vary emission=separate,folded
    motion_study camera-g0-k7 90 $m/camera-g0.toml 7
    # The aligned reprojection against the paper's, with and without spatial reuse (on
    # lavapipe at 160x120 aligned won 1.15-1.30x and spatial reuse lost there).
    motion_study camera-g0-k3-reprojection 120 $m/camera-g0.toml 3 \
        --vary temporal_reprojection=aligned,path --vary spatial_neighbors=0,3
    if [[ -x $plume_bin && ( -z ${NIMBUS_MOTION_ONLY:-} || " $NIMBUS_MOTION_ONLY " == *" plume-k"* ) ]]; then
        step "make plume" "$plume_bin" "$out/plume" 64 96 >"$out/make-plume.log" 2>&1
        motion_study plume-k3 170 "$out/plume/plume-motion-64.toml" 3 \
            --vary spatial_when=camera_moves,camera_or_density
        motion_study plume-k1 100 "$out/plume/plume-motion-64.toml" 1
    fi
    motion_study sun-g0-k1 60 $m/sun-g0.toml 1
    motion_study sun-g0-k7 70 $m/sun-g0.toml 7
    motion_study sky-g06-k1 60 $m/sky-g06.toml 1
    motion_study sky-g06-k7 70 $m/sky-g06.toml 7
    # Last, so that they take no time from the studies above when the command's time runs
    # out (NIMBUS_MOTION_ONLY picks them in a session of their own):
    # Temporal reuse by optical depth against the anchors, at Q = 2 and 8 on the moving
    # frames (on lavapipe at 160x120 it halved a long history's error but lost at Q = 2 for
    # 1.10-1.14x the frame: docs/restir.md, "Temporal reuse by optical depth").
    motion_study camera-g0-k3-tau-shift 110 $m/camera-g0.toml 3 \
        --vary temporal_shift=anchor,optical_depth --vary temporal_limit_moving=2,8
    # Spatial reuse by distance (the default) and by exact optical depth (on lavapipe the
    # exact shift had the lowest error at 1.33x the frame: docs/restir.md, same section).
    motion_study camera-g0-k3-spatial-shift 110 $m/camera-g0.toml 3 \
        --vary spatial_shift=distance,optical_depth_exact
    rm -rf "$out/references" "$out/plume"
    echo "wrote $out"
    exit 0
fi

if [[ $mode == gallery ]]; then
    g="$out/gallery"
    mkdir -p "$g"
    examples="$root/target/release/examples"
    explosion_bin="${NIMBUS_MAKE_EXPLOSION:-$examples/make_explosion}"
    smoke_bin="${NIMBUS_MAKE_SMOKE:-$examples/make_smoke}"
    if [[ -n ${NIMBUS_GALLERY_SMOKE:-} ]]; then
        shot_size=(--width 48 --height 27)
        scale=1
        grid_n=32
        study_size=(--width 32 --height 18 --frames 2 --seeds 1 --reference-frames 2 --reference-spp 1)
    else
        shot_size=(--width 1920 --height 1080)
        scale=4
        grid_n=128
        study_size=(--width 960 --height 540 --frames 8 --seeds 3 --reference-frames 32 --reference-spp 16)
    fi
    if [[ -z ${NIMBUS_GALLERY_ONLY:-} || $NIMBUS_GALLERY_ONLY == *explosion* ]]; then
        step "make explosion" "$explosion_bin" "$out/explosion" "$grid_n" >"$g/make-explosion.log" 2>&1
    fi
    if [[ -z ${NIMBUS_GALLERY_ONLY:-} || $NIMBUS_GALLERY_ONLY == *smoke* ]]; then
        step "make smoke" "$smoke_bin" "$out/smoke" "$grid_n" >"$g/make-smoke.log" 2>&1
    fi
    # Whether step NAME runs: every one, or those named in NIMBUS_GALLERY_ONLY.
    wanted() {
        [[ -z ${NIMBUS_GALLERY_ONLY:-} || " $NIMBUS_GALLERY_ONLY " == *" $1 "* ]]
    }
    # NAME SCENE FRAMES [ARGS...]: one picture at 1080p, then its per-frame profile.
    shot() {
        local name=$1 scene=$2 shot_frames=$3
        shift 3
        wanted "$name" || return 0
        if [[ ! -f $scene ]]; then
            echo "shot $name: no $scene" | tee -a "$out/steps.txt"
            return 0
        fi
        step "render $name" timeout 120 "$NIMBUS_BIN" render "$scene" "${shot_size[@]}" \
            --frames "$shot_frames" "$@" --out "$g/$name.png" >"$g/$name.log" 2>&1
        step "profile $name" timeout 60 "$NIMBUS_BIN" profile "$scene" "${shot_size[@]}" \
            --frames 8 --warmup 2 "$@" >"$g/profile-$name.txt" 2>&1
    }
    baseline=(--set integrator.volume=baseline)
    shot cumulus-baseline assets/scenes/cloud.toml $((4 * scale)) --spp $((4 * scale))
    shot cumulus-restir assets/scenes/cloud-restir.toml $((4 * scale))
    shot explosion-baseline "$out/explosion/explosion-$grid_n.toml" $((4 * scale)) \
        --spp $((4 * scale)) "${baseline[@]}"
    shot explosion-restir "$out/explosion/explosion-$grid_n.toml" $((4 * scale))
    shot smoke-fog "$out/smoke/smoke-fog-$grid_n.toml" $((4 * scale)) --spp $((4 * scale))
    shot window assets/scenes/window.toml $((2 * scale)) --spp 4
    # The GPU denoiser on one 1080p frame of each grid integrator (its report line gives
    # the filter's GPU milliseconds).
    wanted denoise && step "denoise restir" timeout 60 "$NIMBUS_BIN" render assets/scenes/cloud-restir.toml \
        "${shot_size[@]}" --frames 1 --denoise --out "$g/cumulus-restir-1f-denoised.png" \
        >"$g/denoise-restir.log" 2>&1
    wanted denoise && step "denoise baseline" timeout 60 "$NIMBUS_BIN" render assets/scenes/cloud.toml \
        "${shot_size[@]}" --frames 1 --spp 16 --denoise --out "$g/cumulus-baseline-16spp-denoised.png" \
        >"$g/denoise-baseline.log" 2>&1
    # Issue 15's per-frame equal-time metric on the gallery's grid scenes.
    gallery_study() {
        local name=$1 limit=$2 scene=$3
        shift 3
        [[ -f $scene ]] && wanted "study-$name" || return 0
        step "study $name" timeout "$limit" "$NIMBUS_BIN" study "$scene" "${study_size[@]}" \
            --per-frame --cache-dir "$out/references" --vary volume=baseline,restir \
            --vary spp=1,2,4,8,16,32 --baseline volume=baseline "$@" \
            --out-dir "$out/study-$name" >"$out/study-$name.log" 2>&1
    }
    gallery_study cumulus 150 assets/scenes/cloud-restir.toml
    gallery_study explosion 150 "$out/explosion/explosion-$grid_n.toml"
    gallery_study smoke 150 "$out/smoke/smoke-fog-$grid_n.toml"
    for f in "$g"/*.log; do
        [[ $f == */make-* ]] || grep -H "^wrote\|^denoised" "$f" || true
    done >"$g/summary.txt"
    rm -rf "$out/references" "$out/explosion" "$out/smoke"
    echo "wrote $out"
    exit 0
fi

# The cost guard on this device: the benchmark cases' ms and work per sample (counters
# are shown, not judged, on a device other than the baseline's).
step bench nimbus bench --baseline "$root/assets/bench/baseline.json" --json "$out/bench.json" \
    >"$out/bench.txt" 2>&1

# What the driver takes to build the pipelines, from the stripped modules and from the
# whole specialized ones (NIMBUS_STRIP_SHADERS=0; docs/performance.md, "Pipelines built
# from the code a scene reaches"): ReSTIR's at K = 3 and the baseline's, one tiny frame
# each, NVIDIA's disk shader cache off so that every build compiles.
pipelines() {
    local name=$1
    shift
    for volume in restir baseline; do
        step "pipelines $name $volume" env __GL_SHADER_DISK_CACHE=0 NIMBUS_PIPELINE_TIMES=1 "$@" \
            "$NIMBUS_BIN" render assets/scenes/bench/cloud-g0.toml --width 64 --height 36 \
            --frames 1 --set "integrator.volume=$volume" --out "$out/pipelines-$volume.exr" \
            >>"$out/pipelines-$name.txt" 2>&1
    done
}
pipelines stripped
pipelines whole NIMBUS_STRIP_SHADERS=0
rm -f "$out"/pipelines-*.exr

# The test suite on this device (goldens, statistical tests, validation layers).
run_tests() {
    if cargo test --release >"$out/tests.txt" 2>&1; then
        echo "tests passed" | tee -a "$out/tests.txt"
    else
        echo "tests FAILED (see $out/tests.txt)"
        return 1
    fi
}
if ((tests)); then
    step tests run_tests
fi

# Per-pass GPU timings (timestamp queries): the benchmark cloud at 1920x1080 with
# ReSTIR's defaults and the paper's settings (K = 1 and 3) and the baseline's one sample;
# outside --lent also the shipped scenes.
profile() {
    local name=$1
    shift
    nimbus profile "$@" --frames "$frames" >"$out/profile-$name.txt" 2>&1
}
paper=(--set integrator.restir.temporal_limit=4 --set integrator.restir.spatial_neighbors=3
    --set integrator.restir.spatial_when=always
    --set integrator.restir.temporal_history=spatial --set integrator.restir.mip_indirect=2
    --set integrator.restir.mip_reuse=1 --set integrator.restir.nee=one
    --set 'integrator.restir.candidate_tracking="regular"' --set 'integrator.restir.direct="escape"')
for k in 1 3; do
    step "profile restir k$k" profile "bench-restir-hd-k$k" assets/scenes/bench/cloud-g0.toml "${hd[@]}" \
        --set "integrator.max_bounces=$k"
    if [[ $mode != lent ]]; then
        step "profile restir paper k$k" profile "bench-restir-paper-hd-k$k" assets/scenes/bench/cloud-g0.toml \
            "${hd[@]}" --set "integrator.max_bounces=$k" "${paper[@]}"
    fi
    step "profile baseline k$k" profile "bench-baseline-hd-k$k" assets/scenes/bench/cloud-g0.toml "${hd[@]}" \
        --set "integrator.max_bounces=$k" --set integrator.volume=baseline
done
# The settled still frame (64 frames of warm-up: one candidate a frame, Q = 240) with the
# shade cache (the default) and without: on lavapipe shading took 0.12-0.13x and the
# frame 0.48-0.71x with it (docs/performance.md, "Shading a kept path once"); a warp skips
# the evaluation only where all its lanes kept their paths.
for cache in true false; do
    step "profile restir settled k3 shade_cache=$cache" profile "bench-restir-settled-cache-$cache-hd-k3" \
        assets/scenes/bench/cloud-g0.toml "${hd[@]}" --warmup 64 --set "integrator.max_bounces=3" \
        --set "integrator.restir.shade_cache=$cache"
done
# The still temporal pass with the fresh sample's reuse target evaluated (the default,
# "initial" under delta-tracked candidates, evaluates none: 0.10-0.15x that pass on
# lavapipe; docs/performance.md, "The still temporal pass without a target evaluation").
step "profile restir settled k3 still_target=reuse" profile "bench-restir-settled-reuse-target-hd-k3" \
    assets/scenes/bench/cloud-g0.toml "${hd[@]}" --warmup 64 --set "integrator.max_bounces=3" \
    --set 'integrator.restir.still_target="reuse"'
# The one-off diagnostics below were measured on an H200 (docs/performance.md) and are
# left out of --lent, which must fit one lent-machine command.
if [[ $mode != lent ]]; then
# The baseline's density read from a storage buffer instead of the atlas image (what
# density_fetch = "auto" takes on CPU devices; unmeasured on GPUs, which keep the image).
step "profile baseline buffer k3" profile "bench-baseline-buffer-hd-k3" assets/scenes/bench/cloud-g0.toml \
    "${hd[@]}" --set "integrator.max_bounces=3" --set integrator.volume=baseline \
    --set 'integrator.baseline.density_fetch="buffer"'
# ReSTIR's candidates by delta tracking on the exact density instead of regular tracking
# through the piecewise-constant grid (which candidate_tracking = "auto" keeps on this
# static, smooth cloud where the density is read from the atlas; lavapipe, atlas: 1.27x
# the frame for 0.91x the per-frame MSE at K = 3, docs/restir.md "Candidates by delta
# tracking"); the ratio to profile-bench-restir-hd-k3.
step "profile restir delta k3" profile "bench-restir-delta-hd-k3" assets/scenes/bench/cloud-g0.toml \
    "${hd[@]}" --set "integrator.max_bounces=3" --set 'integrator.restir.candidate_tracking="delta"'
# ReSTIR's regular tracking reading sigma* from a storage buffer instead of the atlas
# image (what pc_fetch = "auto" takes on CPU devices: 0.93x a K = 1 frame on lavapipe;
# unmeasured on GPUs, which keep the image); the ratio to profile-bench-restir-hd-k1.
step "profile restir pc buffer k1" profile "bench-restir-pc-buffer-hd-k1" assets/scenes/bench/cloud-g0.toml \
    "${hd[@]}" --set "integrator.max_bounces=1" --set 'integrator.restir.pc_fetch="buffer"'
# ReSTIR reading the density and the march mips from buffers of quads instead of the atlas
# images (what density_fetch = "auto" takes on CPU devices: 0.72-0.83x a frame on
# lavapipe, docs/performance.md; unmeasured on GPUs, which keep the images), with the
# plan's regular tracking; the ratio to profile-bench-restir-hd-k3.
step "profile restir density buffer k3" profile "bench-restir-density-buffer-hd-k3" \
    assets/scenes/bench/cloud-g0.toml "${hd[@]}" --set "integrator.max_bounces=3" \
    --set 'integrator.restir.density_fetch="buffer"' \
    --set 'integrator.restir.candidate_tracking="regular"'
# The same buffers with the delta-tracked candidates that candidate_tracking = "auto"
# takes where the density is read from its buffer (lavapipe: 1.03x the frame for 0.90x the
# per-frame MSE, docs/restir.md "Which tracking once the density is read from a buffer");
# the ratio to profile-bench-restir-delta-hd-k3.
step "profile restir density buffer delta k3" profile "bench-restir-density-buffer-delta-hd-k3" \
    assets/scenes/bench/cloud-g0.toml "${hd[@]}" --set "integrator.max_bounces=3" \
    --set 'integrator.restir.density_fetch="buffer"'
# What SIMD divergence costs the baseline on this device: every workgroup traces its first
# pixel's paths in all its lanes (`--coherent-lanes`); the ratio to profile-bench-baseline-hd-k*
# is the most a wavefront or path-regenerating baseline could win here (2.0-2.3x on
# lavapipe, docs/performance.md "Where a lavapipe frame goes").
for k in 1 3; do
    step "profile baseline coherent k$k" profile "bench-baseline-coherent-hd-k$k" \
        assets/scenes/bench/cloud-g0.toml "${hd[@]}" --set "integrator.max_bounces=$k" \
        --set integrator.volume=baseline --coherent-lanes
done
fi
# What a 1080p ReSTIR frame does per pixel (work counters, K = 3).
step "counters restir k3" profile "counters-restir-hd-k3" assets/scenes/bench/cloud-g0.toml "${hd[@]}" \
    --set "integrator.max_bounces=3" --counters
if [[ $mode != lent ]]; then
    for scene in cloud-restir box-sphere window; do
        step "profile $scene" profile "$scene" "assets/scenes/$scene.toml" "${size[@]}"
    done
fi

# Issue 15's metric: each frame's own error at steady state, ReSTIR (its defaults)
# against the baseline with its spp raised to ReSTIR's frame time (ReSTIR's spp > 1 rows
# are left out by the study), on the benchmark scenes (assets/scenes/bench: a
# 256x160x256 cumulus with g = 0 and 0.8; outside --lent also an HDR sky with a small
# sun and emissive explosions with matched and mismatched colours) at their 320x240.
case $mode in
    quick) bench=(cloud-g08); bench_size=("${size[@]}") ;;
    # On a GPU the benchmark's 320x240 leaves the device idle (launch latency decides
    # the times, docs/performance.md): a quarter of 1080p.
    lent) bench=(cloud-g0 cloud-g08); bench_size=("${lent_study_size[@]}") ;;
    full) bench=(cloud-g0 cloud-g08 sky-sun explosion-matched explosion-mismatched); bench_size=() ;;
esac
if [[ " ${bench[*]} " == *" sky-sun "* && ! -f target/bench/sky-sun.exr ]]; then
    nimbus make-sky target/bench/sky-sun.exr
fi
for scene in "${bench[@]}"; do
    for k in $bounces_list; do
        step "study $scene k$k" nimbus study "assets/scenes/bench/$scene.toml" "${bench_size[@]}" "${ref[@]}" \
            "${cache[@]}" --seeds "$seeds" --per-frame --frames "$frames" \
            --vary "max_bounces=$k" --vary volume=baseline,restir --vary "spp=$spp_list" \
            --baseline volume=baseline --out-dir "$out/study-bench-$scene-k$k"
    done
done

# Issue 26's motion benchmarks (assets/scenes/bench/motion, tools/make_motion_bench.py):
# the same per-frame metric, each measured frame against a reference of that scene frame
# (the window after ReSTIR's warm-up), ReSTIR's defaults against its candidates by
# regular tracking (candidate_tracking) and, outside --lent, Q = 2 and 20 on the frames
# whose camera moved (temporal_limit_moving; lavapipe measured 2 better at 160x120; a
# scene whose camera and density hold still renders both alike, once) and spatial reuse
# on and off (with delta-tracked candidates it lost on lavapipe's moving camera at
# 160x120 and 320x240: docs/restir.md, "Which tracking once the density is read from a
# buffer"); the rotating HDR sky (sky-g06) is the paper's Fig. 4 (top).
case $mode in
    quick) motion=(sun-g0); motion_k=1; motion_vary=() ;;
    # About a minute on an H200: the moving camera at g = 0 with ReSTIR's defaults (the
    # aligned reprojection and spatial reuse, which won there on 2026-11-28:
    # docs/restir.md, "The moving camera on the H200 at 6fe5952").
    lent) motion=(camera-g0); motion_k=3; motion_vary=() ;;
    full) motion=(camera-g0 sun-g0 sky-g06 camera-g08); motion_k=3
        motion_vary=(--vary temporal_limit_moving=2,20 --vary candidate_tracking=delta,regular
            --vary spatial_neighbors=0,3) ;;
esac
if [[ " ${motion[*]} " == *" sky-g06 "* && ! -f target/bench/sky-sun.exr ]]; then
    nimbus make-sky target/bench/sky-sun.exr
fi
for scene in "${motion[@]}"; do
    step "study motion $scene k$motion_k" nimbus study "assets/scenes/bench/motion/$scene.toml" \
        "${bench_size[@]}" --reference-frames "${ref[1]}" --reference-spp 16 "${cache[@]}" \
        --seeds "$seeds" --per-frame --frames 8 --vary "max_bounces=$motion_k" \
        --vary volume=baseline,restir --vary "spp=$spp_list" "${motion_vary[@]}" \
        --baseline volume=baseline --out-dir "$out/study-motion-$scene-k$motion_k"
done

# --lent: the benchmark clouds at K = 7 last (what a cut run loses first).
if [[ $mode == lent ]]; then
    for scene in "${bench[@]}"; do
        step "study $scene k7" nimbus study "assets/scenes/bench/$scene.toml" "${bench_size[@]}" "${ref[@]}" \
            "${cache[@]}" --seeds "$seeds" --per-frame --frames "$frames" \
            --vary max_bounces=7 --vary volume=baseline,restir --vary "spp=$spp_list" \
            --baseline volume=baseline --out-dir "$out/study-bench-$scene-k7"
    done
fi

# What the ReSTIR levers buy at K = 3 (the same metric): split against the paper's NEE,
# spatial reuse on and off, Q = 4 against 20 (the baseline renders once).
lever_k=3
[[ $mode == quick ]] && lever_k=1
[[ $mode == lent ]] || step "study levers" nimbus study "assets/scenes/bench/${bench[0]}.toml" "${bench_size[@]}" "${ref[@]}" \
    "${cache[@]}" --seeds "$seeds" --per-frame --frames "$frames" \
    --vary "max_bounces=$lever_k" --vary volume=baseline,restir --vary "spp=$spp_list" \
    --vary nee=one,split --vary spatial_neighbors=0,3 --vary spatial_when=always --vary temporal_limit=4,20 \
    --baseline volume=baseline --out-dir "$out/study-restir-levers-k$lever_k"

if [[ $mode != lent ]]; then
    # The error of the mean over F frames against the total GPU time (F is the knob),
    # the paper's settings (cloud-restir-study.toml) against the baseline, per K.
    for k in $bounces_list; do
        step "study restir-study k$k" nimbus study assets/scenes/cloud-restir-study.toml "${size[@]}" \
            "${ref[@]}" "${cache[@]}" --seeds "$seeds" --warmup 16 \
            --vary "max_bounces=$k" --vary volume=baseline,restir --vary "frames=$frames_list" \
            --baseline volume=baseline --out-dir "$out/study-restir-k$k"
    done

    # The box-medium paper's estimators at equal time (RM is the baseline of the ratios),
    # ME (moment-based, approximate) beside them: its error floor where its heuristic
    # holds (me-detached) and where it fails (me-interleaved, box-sphere).
    for scene in box-sphere window me-detached me-interleaved; do
        step "study $scene" nimbus study "assets/scenes/$scene.toml" "${size[@]}" "${ref[@]}" "${cache[@]}" \
            --seeds "$seeds" --frames "$frames" \
            --vary box_estimator=mcwvds,reds,rees,rm,mcds,me --vary "box_samples=$box_samples" \
            --baseline box_estimator=rm \
            --out-dir "$out/study-$scene"
    done
fi

# The studies whose GPU times mixed two states of the device (their study.md ends in a
# WARNING: no measurement), named in steps.txt and at the top of summary.md.
mixed=$(grep -l "WARNING: these GPU times" "$out"/study-*/study.md 2>/dev/null || true)
if [[ -n $mixed ]]; then
    echo "mixed device states (not measurements): $(echo $mixed | tr '\n' ' ')" | tee -a "$out/steps.txt"
fi
# One page with every study's equal-time section.
{
    echo "# gpu-check $(date -u +%Y-%m-%dT%H:%M:%SZ) ($mode)"
    echo
    echo '```'
    cat "$out/devices.txt"
    echo
    cat "$out/steps.txt"
    echo '```'
    for f in "$out"/profile-*.txt; do
        [[ -f $f ]] || continue
        echo
        echo "## $(basename "$f" .txt)"
        echo
        echo '```'
        cat "$f"
        echo '```'
    done
    for dir in "$out"/study-*/; do
        [[ -f $dir/study.md ]] || continue
        echo
        echo "## $(basename "$dir")"
        echo
        sed -n '/^## /,$p' "$dir/study.md" | grep -v '^!\[' || true
    done
} >"$out/summary.md"
echo "wrote $out/summary.md"
