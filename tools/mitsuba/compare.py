#!/usr/bin/env python3
"""Side-by-side efficiency of Nimbus (on lavapipe, the CPU Vulkan device) and Mitsuba 3
(llvm_ad_rgb, volpath) on the benchmark cloud, assets/bench/perf-cloud.toml.

Run from the repository root, after `bash tools/mitsuba/setup.sh`:

    target/mitsuba/venv/bin/python tools/mitsuba/compare.py \
        --nimbus target/release/nimbus --vol /tmp/cloud64.vol

The .vol must hold the scene's procedural cloud (`cargo run --example make_cloud --
cloud64.vol 64 64 64 3`); step 0 checks that Nimbus renders it exactly like the procedural
form. Steps:
  0. Nimbus renders perf-cloud.toml and the variant reading the .vol (same seed): the
     images must agree (they do to the bit when the voxels are the same).
  1. A converged reference per configuration (K in {1, 3}, g in {0, 0.8}): Nimbus's
     baseline, 16 spp frames until its relative standard error is <= --ref-error
     (cached in target/mitsuba/refs/, keyed by scene, settings and target).
  2. Agreement: Mitsuba at --check-spp per configuration against the reference: the
     relative difference of the image means, and the per-pixel MSE over the MSE the two
     images' noise explains (1 when they agree everywhere up to noise).
  3. Measurement, interleaved per seed: Nimbus baseline and ReSTIR at several frame counts
     (time = GPU timestamps, `nimbus profile --warmup 1`, median frame ms x frames; the
     image from `nimbus render` with the same seed and settings) and Mitsuba at several
     spp (wall clock around mi.render + sync, the second of two identical renders so no
     JIT compilation is timed).
     nRMSE = RMSE over pixels and RGB / mean of the reference; the reference's own
     variance (its per-pixel stderr^2) is subtracted from the MSE. Efficiency =
     1 / (nRMSE^2 * seconds); the ratio Nimbus / Mitsuba per row.
Writes --out-dir/results.md, results.csv (every measurement) and check.csv.
"""

import argparse
import csv
import datetime
import glob
import hashlib
import json
import math
import os
import platform
import re
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)

# Dr.Jit reads DRJIT_LIBLLVM_PATH when the LLVM backend starts: take setup.sh's.
if "DRJIT_LIBLLVM_PATH" not in os.environ:
    env_sh = os.path.join(ROOT, "target", "mitsuba", "env.sh")
    if os.path.exists(env_sh):
        m = re.search(r'DRJIT_LIBLLVM_PATH="([^"]+)"', open(env_sh).read())
        if m:
            os.environ["DRJIT_LIBLLVM_PATH"] = m.group(1)

import numpy as np  # noqa: E402

from exrio import read_nimbus_exr  # noqa: E402

CONFIGS = [(1, 0.0), (3, 0.0), (1, 0.8), (3, 0.8)]
# The benchmark scene (it moved from assets/scenes/bench/ to assets/bench/).
SCENE_SRC = next((p for p in (os.path.join(ROOT, "assets", "bench", "perf-cloud.toml"),
                              os.path.join(ROOT, "assets", "scenes", "bench", "perf-cloud.toml"))
                  if os.path.exists(p)), os.path.join(ROOT, "assets", "bench", "perf-cloud.toml"))
PROCEDURAL_LINE = 'density = { procedural = "cloud", dims = [64, 64, 64], noise_seed = 3 }'


def log(*a):
    print(*a, file=sys.stderr, flush=True)


def gname(g):
    return ("%g" % g).replace(".", "")


def cfg_name(k, g):
    return "K%d g%g" % (k, g)


# ----------------------------------------------------------------------------- Nimbus


def write_file_scene(work, vol):
    src = open(SCENE_SRC).read()
    if PROCEDURAL_LINE not in src:
        sys.exit("compare.py: %s no longer has the line %r" % (SCENE_SRC, PROCEDURAL_LINE))
    text = src.replace(PROCEDURAL_LINE, 'density = { file = "%s" }' % os.path.abspath(vol))
    text = "# perf-cloud.toml with the density read from a .vol (tools/mitsuba/compare.py)\n" + text
    os.makedirs(work, exist_ok=True)
    path = os.path.join(work, "cloud-file.toml")
    if not os.path.exists(path) or open(path).read() != text:
        with open(path, "w") as f:
            f.write(text)
    return path


# Nimbus's integrators as the rows name them: "restir-fresh" is ReSTIR without temporal
# reuse (fresh candidates every frame, so the frames of a still are independent: the
# still mode docs/performance.md measures).
# "restir": the defaults, which for this static scene's still leave temporal reuse out
# (temporal = "auto"); "restir-temporal" keeps it (the defaults before 2026-12-02).
RESTIR_ROWS = {"restir": "ReSTIR (defaults)", "restir-temporal": "ReSTIR, temporal = true,",
               "restir-fresh": "ReSTIR, temporal = false,"}
RESTIR_DEFAULT_ROWS = ["restir", "restir-temporal"]


def nimbus_sets(k, g, volume):
    sets = ["--set", "integrator.max_bounces=%d" % k, "--set", "medium.1.g=%g" % g]
    if volume == "restir-fresh":
        return sets + ["--set", 'integrator.volume="restir"', "--set", "integrator.restir.temporal=false"]
    if volume == "restir-temporal":
        return sets + ["--set", 'integrator.volume="restir"', "--set", "integrator.restir.temporal=true"]
    return sets + ["--set", 'integrator.volume="%s"' % volume]


def run(cmd, log_path=None):
    t = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    if log_path:
        with open(log_path, "w") as f:
            f.write(" ".join(cmd) + "\n" + p.stdout + p.stderr)
    if p.returncode != 0:
        sys.exit("compare.py: failed (%d): %s\n%s%s" % (p.returncode, " ".join(cmd), p.stdout, p.stderr[-3000:]))
    return p.stdout + p.stderr, time.perf_counter() - t


def nimbus_render(args, scene, k, g, volume, frames, spp, seed, out, extra=(), binary=None):
    cmd = [binary or args.nimbus, "render", scene, *nimbus_sets(k, g, volume), "--frames", str(frames),
           "--spp", str(spp), "--seed", str(seed), "--out", out, *extra]
    text, wall = run(cmd, out + ".log")
    return cmd, text, wall


def nimbus_profile(args, scene, k, g, volume, frames, spp, seed, out_json):
    cmd = [args.nimbus, "profile", scene, *nimbus_sets(k, g, volume), "--frames", str(frames),
           "--warmup", "1", "--spp", str(spp), "--seed", str(seed), "--json", out_json,
           # the frames of the still `nimbus render` makes (temporal = "auto" decides as there)
           "--still"]
    run(cmd, out_json + ".log")
    prof = json.load(open(out_json))
    frame = [p for p in prof["passes"] if p["pass"] == "frame"][0]
    return cmd, frame["median_ms"], prof.get("device", "")


# ----------------------------------------------------------------------------- Mitsuba

_mi = {}


def mitsuba():
    if not _mi:
        import drjit as dr
        import mitsuba as mi
        mi.set_variant("llvm_ad_rgb")
        import mitsuba_scene
        _mi.update(mi=mi, dr=dr, ms=mitsuba_scene, scenes={})
    return _mi


def mitsuba_scene(vol, k, g):
    m = mitsuba()
    key = (k, g)
    if key not in m["scenes"]:
        m["scenes"][key] = m["mi"].load_dict(m["ms"].scene_dict(os.path.abspath(vol), k, g))
    return m["scenes"][key]


def mitsuba_render(vol, k, g, spp, seed):
    """Returns (HxWx3 float64 image, seconds of a render after an identical one)."""
    m = mitsuba()
    mi, dr = m["mi"], m["dr"]
    scene = mitsuba_scene(vol, k, g)
    secs = []
    for _ in range(2):  # the first compiles (or loads) the kernels; time the second
        dr.sync_thread()
        t = time.perf_counter()
        img = mi.render(scene, spp=spp, seed=seed)
        dr.eval(img)
        dr.sync_thread()
        secs.append(time.perf_counter() - t)
        arr = np.array(img, dtype=np.float64)
    return arr[..., :3], secs[1], secs[0]


# ----------------------------------------------------------------------------- errors


def nrmse(img, ref, ref_err):
    mse = np.mean((img - ref) ** 2)
    ref_var = np.mean(ref_err ** 2) if ref_err is not None else 0.0
    return math.sqrt(max(mse - ref_var, 0.0)) / ref.mean(), math.sqrt(mse) / ref.mean()


# ----------------------------------------------------------------------------- steps


def step_file_check(args, scene_file):
    out = os.path.join(args.work, "check")
    os.makedirs(out, exist_ok=True)
    a, b = os.path.join(out, "procedural.exr"), os.path.join(out, "file.exr")
    nimbus_render(args, SCENE_SRC, 3, 0.0, "baseline", 2, 16, 7, a)
    nimbus_render(args, scene_file, 3, 0.0, "baseline", 2, 16, 7, b)
    ia, ea, _ = read_nimbus_exr(a)
    ib, eb, _ = read_nimbus_exr(b)
    maxdiff = float(np.abs(ia - ib).max())
    reldiff = float(ib.mean() / ia.mean() - 1)
    log("procedural vs file: max |diff| %.3g, mean rel diff %.2e" % (maxdiff, reldiff))
    if maxdiff > 0:
        # Not bit-identical: the means must still agree within noise.
        se = math.sqrt(np.mean(ea ** 2) + np.mean(eb ** 2)) / math.sqrt(ia.size)
        if abs(ib.mean() - ia.mean()) > 5 * se:
            sys.exit("compare.py: the .vol scene does not render like the procedural one")
    return {"max_abs_diff": maxdiff, "mean_rel_diff": reldiff}


def ref_path(args, scene_file, k, g):
    if args.any_ref:
        # A cached reference of this configuration, whatever binary rendered it (they are
        # converged images of one scene; a new binary's need not be rendered again).
        found = sorted(glob.glob(os.path.join(args.work, "refs", "ref-k%d-g%s-*.exr" % (k, gname(g)))))
        if found:
            return found[-1]
    h = hashlib.sha256()
    h.update(open(scene_file, "rb").read())
    h.update(open(args.vol, "rb").read())
    h.update(open(args.ref_nimbus, "rb").read())
    h.update(("%d %g %g %d" % (k, g, args.ref_error, args.ref_seed)).encode())
    return os.path.join(args.work, "refs", "ref-k%d-g%s-%s.exr" % (k, gname(g), h.hexdigest()[:12]))


def step_refs(args, scene_file):
    refs = {}
    os.makedirs(os.path.join(args.work, "refs"), exist_ok=True)
    for k, g in CONFIGS:
        path = ref_path(args, scene_file, k, g)
        if not os.path.exists(path):
            log("reference %s: rendering to relative error %g ..." % (cfg_name(k, g), args.ref_error))
            tmp = path + ".part.exr"
            nimbus_render(args, scene_file, k, g, "baseline", 1_000_000, 16, args.ref_seed, tmp,
                          ["--target-error", str(args.ref_error), "--time-limit", str(args.ref_time_limit)],
                          binary=args.ref_nimbus)
            os.replace(tmp, path)
            os.replace(tmp + ".log", path + ".log")
        img, err, hdr = read_nimbus_exr(path)
        info = {"path": os.path.relpath(path, ROOT), "samples": int(hdr["nimbus/samples"]),
                "rel_error": float(hdr["nimbus/rel_error"]), "gpu_s": float(hdr["nimbus/gpu_ms"]) / 1000,
                "mean": float(img.mean()),
                "rel_rms_stderr": float(math.sqrt(np.mean(err ** 2)) / img.mean())}
        log("reference %s: %d spp, rel error %.4f (RGB stderr RMS / mean %.4f), %.0f s"
            % (cfg_name(k, g), info["samples"], info["rel_error"], info["rel_rms_stderr"], info["gpu_s"]))
        refs[(k, g)] = (img, err, info)
    return refs


def agreement_row(config, ref, ref_err, info, imgs, spp_each):
    """Mitsuba against a Nimbus reference: `imgs` are independent Mitsuba renders
    (seeds) of `spp_each` samples per pixel, `ref` / `ref_err` the reference's mean and per-pixel standard error, `info`
    its render info. Returns the agreement table's row and Mitsuba's mean image."""
    n = len(imgs)
    mean = imgs.mean(0)
    var_m = imgs.var(0, ddof=1) / n  # per-pixel variance of the mean
    mse = float(np.mean((mean - ref) ** 2))
    expected = float(np.mean(var_m) + np.mean(ref_err ** 2))
    # Standard error of the relative difference of the means, from both images' noise.
    se_mean = math.sqrt(expected / ref.size) / ref.mean()
    r = {"config": config, "ref_spp": info["samples"], "ref_rel_error": info["rel_rms_stderr"],
         "mitsuba_spp": n * spp_each, "ref_mean": float(ref.mean()), "mitsuba_mean": float(mean.mean()),
         "mean_rel_diff": float(mean.mean() / ref.mean() - 1), "mean_rel_diff_se": se_mean,
         "mse_over_noise": mse / expected}
    for c, name in enumerate("RGB"):
        r["rel_diff_" + name] = float(mean[..., c].mean() / ref[..., c].mean() - 1)
    log("agreement %s: means %.5f (Nimbus) %.5f (Mitsuba), rel diff %+.4f +- %.4f, MSE / noise %.3f"
        % (config, r["ref_mean"], r["mitsuba_mean"], r["mean_rel_diff"], se_mean, r["mse_over_noise"]))
    return r, mean


def agreement_table(agreement, ref_header):
    """The markdown lines of the agreement table (rows of agreement_row); `ref_header`
    names the reference's column."""
    L = ["| config | %s | ref rel error | Mitsuba spp | Nimbus mean | Mitsuba mean | rel diff (+- 1 se) | R / G / B rel diff | MSE / noise |" % ref_header,
         "|---|---|---|---|---|---|---|---|---|"]
    for r in agreement:
        L.append("| %s | %d | %.4f | %d | %.5f | %.5f | %+.5f (+- %.5f) | %+.5f / %+.5f / %+.5f | %.3f |" % (
            r["config"], r["ref_spp"], r["ref_rel_error"], r["mitsuba_spp"], r["ref_mean"], r["mitsuba_mean"],
            r["mean_rel_diff"], r["mean_rel_diff_se"], r["rel_diff_R"], r["rel_diff_G"], r["rel_diff_B"], r["mse_over_noise"]))
    return L


def step_agreement(args, refs):
    rows = []
    chunk = min(args.check_spp, 256)
    n = max(args.check_spp // chunk, 2)
    for k, g in CONFIGS:
        ref, ref_err, info = refs[(k, g)]
        cache = os.path.join(args.work, "check", "mitsuba-k%d-g%s-%dx%d.npy" % (k, gname(g), n, chunk))
        if os.path.exists(cache):
            imgs = np.load(cache)
        else:
            imgs = np.stack([mitsuba_render(args.vol, k, g, chunk, 5000 + i)[0] for i in range(n)])
            np.save(cache, imgs)
        r, _ = agreement_row(cfg_name(k, g), ref, ref_err, info, imgs, chunk)
        rows.append(r)
    return rows


def step_measure(args, scene_file, refs):
    out = os.path.join(args.work, "runs")
    os.makedirs(out, exist_ok=True)
    rows = []
    nb_levels = [int(x) for x in args.nimbus_frames.split(",")]
    rs_levels = [int(x) for x in args.restir_frames.split(",")]
    mi_levels = [int(x) for x in args.mitsuba_spp.split(",")]

    def nimbus_one(k, g, volume, frames, spp, seed):
        ref, ref_err, _ = refs[(k, g)]
        tag = "%s-k%d-g%s-f%d-s%d-seed%d" % (volume, k, gname(g), frames, spp, seed)
        load = os.getloadavg()[0]
        pcmd, median_ms, device = nimbus_profile(args, scene_file, k, g, volume, frames, spp, seed,
                                                 os.path.join(out, tag + ".json"))
        exr = os.path.join(out, tag + ".exr")
        rcmd, _, wall = nimbus_render(args, scene_file, k, g, volume, frames, spp, seed, exr)
        img, _, hdr = read_nimbus_exr(exr)
        e, e_raw = nrmse(img, ref, ref_err)
        secs = median_ms * frames / 1000
        r = {"renderer": "nimbus", "integrator": volume, "k": k, "g": g, "seed": seed,
             "frames": frames, "spp": spp, "samples": frames * spp, "median_frame_ms": median_ms,
             "seconds": secs, "render_gpu_s": float(hdr["nimbus/gpu_ms"]) / 1000, "render_wall_s": wall,
             "nrmse": e, "nrmse_uncorrected": e_raw, "efficiency": 1 / (e * e * secs),
             "load1": load, "device": device}
        log("  nimbus %-8s %s seed %d: %4d x %2d spp, %7.1f ms/frame, %6.2f s, nRMSE %.4f, eff %.3g"
            % (volume, cfg_name(k, g), seed, frames, spp, median_ms, secs, e, r["efficiency"]))
        rows.append(r)

    def mitsuba_one(k, g, spp, seed):
        ref, ref_err, _ = refs[(k, g)]
        load = os.getloadavg()[0]
        img, secs, first = mitsuba_render(args.vol, k, g, spp, seed)
        e, e_raw = nrmse(img, ref, ref_err)
        r = {"renderer": "mitsuba", "integrator": "volpath", "k": k, "g": g, "seed": seed,
             "frames": 1, "spp": spp, "samples": spp, "median_frame_ms": "", "seconds": secs,
             "render_gpu_s": "", "render_wall_s": first, "nrmse": e, "nrmse_uncorrected": e_raw,
             "efficiency": 1 / (e * e * secs), "load1": load, "device": "llvm_ad_rgb"}
        log("  mitsuba volpath  %s seed %d: %4d spp, %6.2f s (first %.2f s), nRMSE %.4f, eff %.3g"
            % (cfg_name(k, g), seed, spp, secs, first, e, r["efficiency"]))
        rows.append(r)

    for seed in args.seeds:
        for k, g in CONFIGS:
            for i in range(max(len(nb_levels), len(mi_levels))):
                if i < len(nb_levels):
                    nimbus_one(k, g, "baseline", nb_levels[i], args.nimbus_spp, seed)
                if i < len(mi_levels):
                    mitsuba_one(k, g, mi_levels[i], seed)
                if (k, g) == (3, 0.0) and i < len(rs_levels):
                    for mode in args.restir:
                        nimbus_one(k, g, mode, rs_levels[i], 1, seed)
    return rows


# ----------------------------------------------------------------------------- report


def gmean(xs):
    return math.exp(sum(math.log(x) for x in xs) / len(xs))


def means_by_samples(rs):
    """One row per sample count of `rs`, its frame ms, seconds and nRMSE the means over
    the runs (seeds) with that count (compare_box.py's tables too)."""
    out = []
    for n in sorted({r["samples"] for r in rs}):
        sel = [r for r in rs if r["samples"] == n]
        mean = dict(sel[0])
        for key in ("median_frame_ms", "seconds", "nrmse"):
            if mean[key] != "":
                mean[key] = sum(r[key] for r in sel) / len(sel)
        out.append(mean)
    return out


def summarize(rows, seeds):
    """Per table row: Nimbus integrator x config. Efficiency per renderer = geometric mean
    over its sample counts; the ratio per seed, then over seeds."""
    table = []
    keys = [("baseline", k, g) for k, g in CONFIGS] + [(mode, 3, 0.0) for mode in RESTIR_ROWS]
    for integ, k, g in keys:
        nb = [r for r in rows if r["renderer"] == "nimbus" and r["integrator"] == integ and r["k"] == k and r["g"] == g]
        mi = [r for r in rows if r["renderer"] == "mitsuba" and r["k"] == k and r["g"] == g]
        if not nb or not mi:
            continue
        ratios = []
        for s in seeds:
            a = [r["efficiency"] for r in nb if r["seed"] == s]
            b = [r["efficiency"] for r in mi if r["seed"] == s]
            if a and b:
                ratios.append(gmean(a) / gmean(b))

        def levels(rs, fmt):
            return [fmt(m, m["seconds"], m["nrmse"]) for m in means_by_samples(rs)]

        # Contention-robust variant: each run timed at its renderer's fastest seconds per
        # sample over all runs of this row (the machine is shared; the fastest run is the
        # one least disturbed), so only the errors differ between runs.
        def best_eff(rs):
            best = min(r["seconds"] / r["samples"] for r in rs)
            return gmean([1 / (r["nrmse"] ** 2 * best * r["samples"]) for r in rs]), best

        eff_nb, best_nb = best_eff(nb)
        eff_mi, best_mi = best_eff(mi)

        table.append({
            "ratio_best": eff_nb / eff_mi, "best_ms_per_sample": (1000 * best_nb, 1000 * best_mi),
            "config": "%s %s" % (RESTIR_ROWS.get(integ, integ), cfg_name(k, g)),
            "nimbus": levels(nb, lambda r, s, e: ("%dx%d: %.0f ms/fr, %.2f s" % (r["frames"], r["spp"], r["median_frame_ms"], s), e)),
            "mitsuba": levels(mi, lambda r, s, e: ("%d spp: %.2f s" % (r["spp"], s), e)),
            "ratio": gmean(ratios), "ratio_min": min(ratios), "ratio_max": max(ratios), "ratios": ratios,
        })
    return table


def markdown(args, meta, file_check, agreement, table):
    L = []
    L.append("# Nimbus vs Mitsuba 3: efficiency on the benchmark cloud (CPU)")
    L.append("")
    L.append("Made by `tools/mitsuba/compare.py` on %s (%s). Scene: `%s` "
             "(128x128, 64^3 cloud, sigma_t <= 20/m, albedo 0.9, sun + constant sky), density read from the "
             "same `.vol` by both renderers." % (meta["date"], meta["machine"], os.path.relpath(SCENE_SRC, ROOT)))
    L.append("")
    L.append("- Nimbus: %s, %s; time = GPU timestamps (`nimbus profile --warmup 1`, median frame ms x frames)." % (meta["nimbus"], meta["nimbus_device"]))
    L.append("- Mitsuba %s `llvm_ad_rgb`, `volpath` (max_depth = K + 1, no Russian roulette), independent sampler, box filter; "
             "time = wall clock of `mi.render` + sync, the second of two identical renders (no JIT)." % meta["mitsuba"])
    L.append("- %d cores; seeds %s; load average (1 min) during the runs %.2f..%.2f." % (os.cpu_count(), ", ".join(map(str, args.seeds)), meta["load_min"], meta["load_max"]))
    L.append("- nRMSE = RMSE over pixels and RGB / reference mean, with the reference's own variance subtracted; "
             "efficiency = 1 / (nRMSE^2 s); ratio = Nimbus / Mitsuba (geometric mean over sample counts, then seeds; min..max over seeds).")
    L.append("- Procedural vs `.vol` density in Nimbus (same seed): max |diff| %.3g, mean rel diff %.1e."
             % (file_check["max_abs_diff"], file_check["mean_rel_diff"]))
    L.append("")
    L.append("## References and agreement")
    L.append("")
    L += agreement_table(agreement, "reference spp")
    L.append("")
    L.append("MSE / noise: the per-pixel MSE between Mitsuba's image and the reference over what the two images' "
             "variances explain; 1 = the same image up to noise.")
    L.append("")
    L.append("## Efficiency")
    L.append("")
    L.append("| config | Nimbus (frames x spp: ms/frame, time) | Nimbus nRMSE | Mitsuba (spp: time) | Mitsuba nRMSE | efficiency Nimbus / Mitsuba (min..max over seeds) | ratio at fastest ms/sample (Nimbus, Mitsuba) |")
    L.append("|---|---|---|---|---|---|---|")
    for t in table:
        L.append("| %s | %s | %s | %s | %s | **%.2f** (%.2f..%.2f) | %.2f (%.1f, %.1f ms) |" % (
            t["config"], "<br>".join(x for x, _ in t["nimbus"]), "<br>".join("%.4f" % e for _, e in t["nimbus"]),
            "<br>".join(x for x, _ in t["mitsuba"]), "<br>".join("%.4f" % e for _, e in t["mitsuba"]),
            t["ratio"], t["ratio_min"], t["ratio_max"], t["ratio_best"], *t["best_ms_per_sample"]))
    L.append("")
    L.append("Times and nRMSE are means over seeds; every measurement is in `results.csv`. The last column "
             "times every run at its renderer's fastest seconds per sample (per spp; per frame for ReSTIR) "
             "over the row's runs, which takes out most of the shared machine's timing noise.")
    L.append("")
    L.append("Command: `%s`" % meta["command"])
    return "\n".join(L) + "\n"


def read_csv(path):
    out = []
    for r in csv.DictReader(open(path)):
        row = {}
        for k, v in r.items():
            try:
                row[k] = int(v)
            except ValueError:
                try:
                    row[k] = float(v)
                except ValueError:
                    row[k] = v
        out.append(row)
    return out


def write_csv(path, rows):
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        for r in rows:
            w.writerow({k: ("%.6g" % v if isinstance(v, float) else v) for k, v in r.items()})


def report_only(args):
    """Rewrites results.md from the CSVs; with --merge DIR..., first merges the
    results.csv of other runs' out-dirs (other seeds) into --out-dir's."""
    rows = read_csv(os.path.join(args.out_dir, "results.csv"))
    agreement = read_csv(os.path.join(args.out_dir, "check.csv"))
    meta = json.load(open(os.path.join(args.out_dir, "meta.json")))
    commands = [meta["command"]]
    for d in args.merge or []:
        extra = read_csv(os.path.join(d, "results.csv"))
        if {r["seed"] for r in extra} & {r["seed"] for r in rows}:
            sys.exit("compare.py: %s repeats seeds of %s" % (d, args.out_dir))
        rows += extra
        commands.append(json.load(open(os.path.join(d, "meta.json")))["command"])
    if args.merge:
        write_csv(os.path.join(args.out_dir, "results.csv"), rows)
        meta["command"] = "`; then `".join(commands + [" ".join(
            [os.path.relpath(sys.executable, ROOT) if sys.executable.startswith(ROOT) else sys.executable,
             os.path.relpath(os.path.abspath(sys.argv[0]), ROOT)] + sys.argv[1:])])
        meta["load_min"] = min(r["load1"] for r in rows)
        meta["load_max"] = max(r["load1"] for r in rows)
        with open(os.path.join(args.out_dir, "meta.json"), "w") as f:
            json.dump(meta, f, indent=1)
    args.seeds = sorted({r["seed"] for r in rows})
    md = markdown(args, meta, meta["file_check"], agreement, summarize(rows, args.seeds))
    with open(os.path.join(args.out_dir, "results.md"), "w") as f:
        f.write(md)
    print(md)


def main():
    global SCENE_SRC
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--nimbus", default=os.path.join(ROOT, "target", "release", "nimbus"))
    ap.add_argument("--ref-nimbus", default=None,
                    help="the binary that renders (and keys) the references; default --nimbus. "
                         "References are converged images: reuse an older build's after a change "
                         "that only touches speed or noise")
    ap.add_argument("--scene", default=SCENE_SRC, help="the procedural benchmark scene")
    ap.add_argument("--vol", default="/tmp/cloud64.vol")
    ap.add_argument("--work", default=os.path.join(ROOT, "target", "mitsuba"))
    ap.add_argument("--out-dir", default=os.path.join(ROOT, "docs", "mitsuba-compare"))
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--ref-error", type=float, default=0.004)
    ap.add_argument("--ref-seed", type=int, default=1000)
    ap.add_argument("--ref-time-limit", type=float, default=3600)
    ap.add_argument("--check-spp", type=int, default=1024)
    ap.add_argument("--nimbus-frames", default="16,64", help="baseline frame counts")
    ap.add_argument("--nimbus-spp", type=int, default=16)
    ap.add_argument("--restir-frames", default="64,256", help="ReSTIR frame counts (1 spp)")
    ap.add_argument("--restir", nargs="+", default=RESTIR_DEFAULT_ROWS, choices=list(RESTIR_ROWS),
                    help="ReSTIR rows (K = 3, g = 0): its defaults (a still without temporal reuse), with it, and with temporal = false")
    ap.add_argument("--configs", nargs="+", default=["%d:%g" % c for c in CONFIGS], metavar="K:G",
                    help="the configurations (max_bounces:g) to compare, e.g. 3:0")
    ap.add_argument("--mitsuba-spp", default="64,256")
    ap.add_argument("--stop-after", choices=["refs", "agreement"], help="stop after this step")
    ap.add_argument("--any-ref", action="store_true",
                    help="take a cached reference of each configuration whatever binary rendered it")
    ap.add_argument("--report-only", action="store_true",
                    help="rewrite results.md from --out-dir's results.csv and check.csv, rendering nothing")
    ap.add_argument("--merge", nargs="+", metavar="DIR",
                    help="with --report-only: add the measurements of these out-dirs (other seeds)")
    args = ap.parse_args()
    args.nimbus = os.path.abspath(args.nimbus)
    args.ref_nimbus = os.path.abspath(args.ref_nimbus or args.nimbus)
    SCENE_SRC = os.path.abspath(args.scene)
    try:
        CONFIGS[:] = [(int(c.split(":")[0]), float(c.split(":")[1])) for c in args.configs]
    except (IndexError, ValueError):
        sys.exit("compare.py: --configs takes K:G pairs such as 3:0, got %s" % " ".join(args.configs))

    if args.report_only:
        return report_only(args)
    scene_file = write_file_scene(args.work, args.vol)
    file_check = step_file_check(args, scene_file)
    refs = step_refs(args, scene_file)
    if args.stop_after == "refs":
        return
    agreement = step_agreement(args, refs)
    bad = [r for r in agreement if abs(r["mean_rel_diff"]) > 0.01]
    if bad:
        log("WARNING: Mitsuba's mean differs from the reference by more than 1%% in %s"
            % ", ".join(r["config"] for r in bad))
    if args.stop_after == "agreement":
        return
    rows = step_measure(args, scene_file, refs)
    table = summarize(rows, args.seeds)

    m = mitsuba()
    version = run([args.nimbus, "--version"])[0].strip()
    meta = {
        "date": datetime.datetime.now().strftime("%Y-%m-%d %H:%M"),
        "machine": "%s %s, %s" % (platform.system(), platform.machine(), open("/proc/cpuinfo").read().split("model name")[1].split("\n")[0].strip(": \t")),
        "nimbus": version,
        "nimbus_device": rows[0]["device"],
        "mitsuba": m["mi"].__version__,
        "load_min": min(r["load1"] for r in rows),
        "load_max": max(r["load1"] for r in rows),
        "command": " ".join([os.path.relpath(sys.executable, ROOT) if sys.executable.startswith(ROOT) else sys.executable,
                             os.path.relpath(os.path.abspath(sys.argv[0]), ROOT)] + sys.argv[1:]),
    }
    os.makedirs(args.out_dir, exist_ok=True)
    md = markdown(args, meta, file_check, agreement, table)
    with open(os.path.join(args.out_dir, "results.md"), "w") as f:
        f.write(md)
    with open(os.path.join(args.out_dir, "meta.json"), "w") as f:
        json.dump(dict(meta, file_check=file_check), f, indent=1)
    write_csv(os.path.join(args.out_dir, "results.csv"), rows)
    with open(os.path.join(args.out_dir, "check.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(agreement[0].keys()))
        w.writeheader()
        for r in agreement:
            w.writerow({k: ("%.6g" % v if isinstance(v, float) else v) for k, v in r.items()})
    print(md)


if __name__ == "__main__":
    main()
