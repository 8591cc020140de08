#!/usr/bin/env python3
"""Side-by-side efficiency of Nimbus's box-medium estimators (on lavapipe) and Mitsuba 3
(llvm_ad_rgb, volpath) on a box-medium scene: by default the box-medium paper's setup,
assets/scenes/box-sphere.toml (a rotated box of fog, sigma_t 1.2/m, albedo 0.9, g 0.3, a
sphere inside it casting a shadow volume, a sun and a dim constant sky).

Run from the repository root, after `bash tools/mitsuba/setup.sh`:

    target/mitsuba/venv/bin/python tools/mitsuba/compare_box.py --nimbus target/release/nimbus

Both renderers read the one scene file (box_scene.py translates it, refusing what it
cannot translate); Nimbus renders it with its pixel rays jittered over the pixel (the
scene file's pixel-centre rays are for estimator studies; Mitsuba's box filter jitters).
Steps, as compare.py's:
  1. A converged reference per K (--ks): Nimbus, MCWVDS, 4-spp frames until the relative
     standard error is <= --ref-error (cached in target/mitsuba/refs-box/, keyed by the
     scene, the settings and the binary).
  2. Agreement: Mitsuba at --check-spp per K against the reference: the relative
     difference of the means, and the per-pixel MSE over the MSE the two images' noise
     explains (1 when they agree everywhere up to noise).
  3. Measurement, interleaved per seed: Nimbus with each of --estimators at several frame
     counts (time = GPU timestamps, `nimbus profile --warmup 1`, median frame ms x frames;
     the image from `nimbus render`, same seed and settings) and Mitsuba at several spp
     (wall clock around mi.render + sync, the second of two identical renders).
     Efficiency = 1 / (nRMSE^2 s), nRMSE with the reference's own variance subtracted.
Writes --out-dir/results.md, results.csv and check.csv.
"""

import argparse
import datetime
import hashlib
import json
import math
import os
import platform
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import compare as C  # noqa: E402  (sets DRJIT_LIBLLVM_PATH from setup.sh's env.sh)
import numpy as np  # noqa: E402

from exrio import read_nimbus_exr  # noqa: E402

ROOT = C.ROOT
SCENE = os.path.join(ROOT, "assets", "scenes", "box-sphere.toml")


def nimbus_sets(k, estimator, samples):
    return ["--set", "integrator.max_bounces=%d" % k, "--set", 'integrator.box_estimator="%s"' % estimator,
            "--set", "integrator.box_samples=%d" % samples, "--set", "render.pixel_jitter=true"]


def nimbus_render(args, k, estimator, frames, spp, seed, out, extra=(), binary=None):
    cmd = [binary or args.nimbus, "render", args.scene, *nimbus_sets(k, estimator, args.box_samples),
           "--frames", str(frames), "--spp", str(spp), "--seed", str(seed), "--out", out, *extra]
    return C.run(cmd, out + ".log")


def nimbus_profile(args, k, estimator, frames, spp, seed, out_json):
    cmd = [args.nimbus, "profile", args.scene, *nimbus_sets(k, estimator, args.box_samples),
           "--frames", str(frames), "--warmup", "1", "--spp", str(spp), "--seed", str(seed), "--json", out_json]
    C.run(cmd, out_json + ".log")
    prof = json.load(open(out_json))
    frame = [p for p in prof["passes"] if p["pass"] == "frame"][0]
    return frame["median_ms"], prof.get("device", "")


_scenes = {}


def mitsuba_render(args, k, spp, seed):
    """(HxWx3 image, seconds of a render after an identical one, seconds of the first)."""
    m = C.mitsuba()
    mi, dr = m["mi"], m["dr"]
    if k not in _scenes:
        import box_scene
        _scenes[k] = mi.load_dict(box_scene.scene_dict(args.scene, k))
    secs = []
    for _ in range(2):
        dr.sync_thread()
        t = time.perf_counter()
        img = mi.render(_scenes[k], spp=spp, seed=seed)
        dr.eval(img)
        dr.sync_thread()
        secs.append(time.perf_counter() - t)
        arr = np.array(img, dtype=np.float64)
    return arr[..., :3], secs[1], secs[0]


def ref_path(args, k):
    h = hashlib.sha256()
    h.update(open(args.scene, "rb").read())
    h.update(open(args.ref_nimbus, "rb").read())
    h.update(("%d %d %g %d" % (k, args.box_samples, args.ref_error, args.ref_seed)).encode())
    return os.path.join(args.work, "refs-box", "ref-k%d-%s.exr" % (k, h.hexdigest()[:12]))


def step_refs(args):
    refs = {}
    os.makedirs(os.path.join(args.work, "refs-box"), exist_ok=True)
    for k in args.ks:
        path = ref_path(args, k)
        if not os.path.exists(path):
            C.log("reference K%d: rendering to relative error %g ..." % (k, args.ref_error))
            tmp = path + ".part.exr"
            nimbus_render(args, k, "mcwvds", 1_000_000, 4, args.ref_seed, tmp,
                          ["--target-error", str(args.ref_error), "--time-limit", str(args.ref_time_limit)],
                          binary=args.ref_nimbus)
            os.replace(tmp, path)
            os.replace(tmp + ".log", path + ".log")
        img, err, hdr = read_nimbus_exr(path)
        info = {"samples": int(hdr["nimbus/samples"]), "rel_rms_stderr": float(math.sqrt(np.mean(err ** 2)) / img.mean()),
                "gpu_s": float(hdr["nimbus/gpu_ms"]) / 1000}
        C.log("reference K%d: %d spp, RGB stderr RMS / mean %.4f, %.0f s" % (k, info["samples"], info["rel_rms_stderr"], info["gpu_s"]))
        refs[k] = (img, err, info)
    return refs


def step_agreement(args, refs):
    rows = []
    chunk = min(args.check_spp, 256)
    n = max(args.check_spp // chunk, 2)
    for k in args.ks:
        ref, ref_err, info = refs[k]
        imgs = np.stack([mitsuba_render(args, k, chunk, 5000 + i)[0] for i in range(n)])
        r, mean = C.agreement_row("K%d" % k, ref, ref_err, info, imgs, chunk)
        np.save(os.path.join(args.work, "refs-box", "mitsuba-k%d-%dspp.npy" % (k, n * chunk)), mean)
        rows.append(r)
    return rows


def step_measure(args, refs):
    out = os.path.join(args.work, "runs-box")
    os.makedirs(out, exist_ok=True)
    rows = []
    nb_levels = [int(x) for x in args.nimbus_frames.split(",")]
    mi_levels = [int(x) for x in args.mitsuba_spp.split(",")]

    def nimbus_one(k, est, frames, seed):
        ref, ref_err, _ = refs[k]
        tag = "%s-k%d-f%d-s%d-n%d-seed%d" % (est, k, frames, args.nimbus_spp, args.box_samples, seed)
        load = os.getloadavg()[0]
        median_ms, device = nimbus_profile(args, k, est, frames, args.nimbus_spp, seed, os.path.join(out, tag + ".json"))
        exr = os.path.join(out, tag + ".exr")
        _, wall = nimbus_render(args, k, est, frames, args.nimbus_spp, seed, exr)
        img, _, _ = read_nimbus_exr(exr)
        e, e_raw = C.nrmse(img, ref, ref_err)
        secs = median_ms * frames / 1000
        r = {"renderer": "nimbus", "integrator": est, "k": k, "seed": seed, "frames": frames,
             "spp": args.nimbus_spp, "samples": frames * args.nimbus_spp, "median_frame_ms": median_ms,
             "seconds": secs, "render_wall_s": wall, "nrmse": e, "nrmse_uncorrected": e_raw,
             "efficiency": 1 / (e * e * secs), "load1": load, "device": device}
        C.log("  nimbus %-6s K%d seed %d: %4d x %d spp, %7.1f ms/frame, %6.2f s, nRMSE %.4f, eff %.3g"
              % (est, k, seed, frames, args.nimbus_spp, median_ms, secs, e, r["efficiency"]))
        rows.append(r)

    def mitsuba_one(k, spp, seed):
        ref, ref_err, _ = refs[k]
        load = os.getloadavg()[0]
        img, secs, first = mitsuba_render(args, k, spp, seed)
        e, e_raw = C.nrmse(img, ref, ref_err)
        r = {"renderer": "mitsuba", "integrator": "volpath", "k": k, "seed": seed, "frames": 1, "spp": spp,
             "samples": spp, "median_frame_ms": "", "seconds": secs, "render_wall_s": first, "nrmse": e,
             "nrmse_uncorrected": e_raw, "efficiency": 1 / (e * e * secs), "load1": load, "device": "llvm_ad_rgb"}
        C.log("  mitsuba volpath K%d seed %d: %5d spp, %6.2f s (first %.2f s), nRMSE %.4f, eff %.3g"
              % (k, seed, spp, secs, first, e, r["efficiency"]))
        rows.append(r)

    for seed in args.seeds:
        for k in args.ks:
            for i in range(max(len(nb_levels), len(mi_levels))):
                for est in args.estimators:
                    if i < len(nb_levels):
                        nimbus_one(k, est, nb_levels[i], seed)
                if i < len(mi_levels):
                    mitsuba_one(k, mi_levels[i], seed)
    return rows


def summarize(args, rows):
    table = []
    for k in args.ks:
        mi_rows = [r for r in rows if r["renderer"] == "mitsuba" and r["k"] == k]
        for est in args.estimators:
            nb = [r for r in rows if r["renderer"] == "nimbus" and r["integrator"] == est and r["k"] == k]
            if not nb or not mi_rows:
                continue
            ratios = []
            for s in args.seeds:
                a = [r["efficiency"] for r in nb if r["seed"] == s]
                b = [r["efficiency"] for r in mi_rows if r["seed"] == s]
                if a and b:
                    ratios.append(C.gmean(a) / C.gmean(b))

            def levels(rs, fmt):
                return [(fmt(m), m["nrmse"]) for m in C.means_by_samples(rs)]

            table.append({
                "config": "%s K%d" % (est.upper(), k),
                "nimbus": levels(nb, lambda r: "%dx%d: %.1f ms/fr, %.2f s" % (r["frames"], r["spp"], r["median_frame_ms"], r["seconds"])),
                "mitsuba": levels(mi_rows, lambda r: "%d spp: %.2f s" % (r["spp"], r["seconds"])),
                "ratio": C.gmean(ratios), "ratio_min": min(ratios), "ratio_max": max(ratios),
            })
    return table


def markdown(args, meta, agreement, table):
    L = ["# Nimbus vs Mitsuba 3: efficiency on a box medium (CPU)", ""]
    L.append("Made by `tools/mitsuba/compare_box.py` on %s (%s). Scene: `%s` (the box-medium paper's setup), "
             "read by both renderers; Nimbus with jittered pixel rays, %d samples per segment (`box_samples`)."
             % (meta["date"], meta["machine"], os.path.relpath(args.scene, ROOT), args.box_samples))
    L.append("")
    L.append("- Nimbus: %s, %s; time = GPU timestamps (`nimbus profile --warmup 1`, median frame ms x frames)." % (meta["nimbus"], meta["nimbus_device"]))
    L.append("- Mitsuba %s `llvm_ad_rgb`, `volpath` (max_depth = K + 1, no Russian roulette); time = wall clock of "
             "`mi.render` + sync, the second of two identical renders." % meta["mitsuba"])
    L.append("- %d cores; seeds %s; load average (1 min) %.2f..%.2f." % (os.cpu_count(), ", ".join(map(str, args.seeds)), meta["load_min"], meta["load_max"]))
    L.append("- nRMSE = RMSE over pixels and RGB / reference mean, the reference's variance subtracted; efficiency = "
             "1 / (nRMSE^2 s); ratio = Nimbus / Mitsuba (geometric mean over sample counts, then seeds; min..max over seeds).")
    L.append("")
    L.append("## Reference and agreement")
    L.append("")
    L += C.agreement_table(agreement, "reference spp (Nimbus MCWVDS)")
    L.append("")
    L.append("## Efficiency")
    L.append("")
    L.append("| estimator, K | Nimbus (frames x spp: ms/frame, time) | Nimbus nRMSE | Mitsuba (spp: time) | Mitsuba nRMSE | efficiency Nimbus / Mitsuba (min..max over seeds) |")
    L.append("|---|---|---|---|---|---|")
    for t in table:
        L.append("| %s | %s | %s | %s | %s | **%.1f** (%.1f..%.1f) |" % (
            t["config"], "<br>".join(x for x, _ in t["nimbus"]), "<br>".join("%.4f" % e for _, e in t["nimbus"]),
            "<br>".join(x for x, _ in t["mitsuba"]), "<br>".join("%.4f" % e for _, e in t["mitsuba"]),
            t["ratio"], t["ratio_min"], t["ratio_max"]))
    L.append("")
    L.append("Command: `%s`" % meta["command"])
    return "\n".join(L) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--nimbus", default=os.path.join(ROOT, "target", "release", "nimbus"))
    ap.add_argument("--ref-nimbus", default=None, help="the binary that renders (and keys) the references")
    ap.add_argument("--scene", default=SCENE)
    ap.add_argument("--work", default=os.path.join(ROOT, "target", "mitsuba"))
    ap.add_argument("--out-dir", default=os.path.join(ROOT, "docs", "mitsuba-compare", "box"))
    ap.add_argument("--ks", type=int, nargs="+", default=[1, 3])
    ap.add_argument("--estimators", nargs="+", default=["mcwvds", "reds"])
    ap.add_argument("--box-samples", type=int, default=8)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--ref-error", type=float, default=0.002)
    ap.add_argument("--ref-seed", type=int, default=1000)
    ap.add_argument("--ref-time-limit", type=float, default=1800)
    ap.add_argument("--check-spp", type=int, default=4096)
    ap.add_argument("--nimbus-frames", default="16,64")
    ap.add_argument("--nimbus-spp", type=int, default=4)
    ap.add_argument("--mitsuba-spp", default="64,256")
    ap.add_argument("--stop-after", choices=["refs", "agreement"])
    args = ap.parse_args()
    args.nimbus = os.path.abspath(args.nimbus)
    args.ref_nimbus = os.path.abspath(args.ref_nimbus or args.nimbus)
    args.scene = os.path.abspath(args.scene)

    refs = step_refs(args)
    if args.stop_after == "refs":
        return
    agreement = step_agreement(args, refs)
    bad = [r for r in agreement if abs(r["mean_rel_diff"]) > max(0.01, 4 * r["mean_rel_diff_se"])]
    if bad:
        C.log("WARNING: Mitsuba's mean differs from the reference in %s" % ", ".join(r["config"] for r in bad))
    if args.stop_after == "agreement":
        return
    rows = step_measure(args, refs)
    table = summarize(args, rows)
    m = C.mitsuba()
    meta = {
        "date": datetime.datetime.now().strftime("%Y-%m-%d %H:%M"),
        "machine": "%s %s, %s" % (platform.system(), platform.machine(), open("/proc/cpuinfo").read().split("model name")[1].split("\n")[0].strip(": \t")),
        "nimbus": C.run([args.nimbus, "--version"])[0].strip(),
        "nimbus_device": rows[0]["device"],
        "mitsuba": m["mi"].__version__,
        "load_min": min(r["load1"] for r in rows),
        "load_max": max(r["load1"] for r in rows),
        "command": " ".join([os.path.relpath(sys.executable, ROOT) if sys.executable.startswith(ROOT) else sys.executable,
                             os.path.relpath(os.path.abspath(sys.argv[0]), ROOT)] + sys.argv[1:]),
    }
    os.makedirs(args.out_dir, exist_ok=True)
    md = markdown(args, meta, agreement, table)
    with open(os.path.join(args.out_dir, "results.md"), "w") as f:
        f.write(md)
    with open(os.path.join(args.out_dir, "meta.json"), "w") as f:
        json.dump(meta, f, indent=1)
    C.write_csv(os.path.join(args.out_dir, "results.csv"), rows)
    C.write_csv(os.path.join(args.out_dir, "check.csv"), agreement)
    print(md)


if __name__ == "__main__":
    main()
