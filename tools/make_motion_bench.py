#!/usr/bin/env python3
"""Writes the motion benchmarks of issue 26 into assets/scenes/bench/motion/.

    python3 tools/make_motion_bench.py [OUT_DIR]

Each scene is a static benchmark of assets/scenes/bench/ (the procedural 256x160x256
cumulus at 320x240) with one thing moving over 128 frames, keyed every 8 frames (the
scene format interpolates linearly in between, and holds the last key after frame 128):

- camera-g0 / camera-g08: the camera orbits 40 degrees about the cloud's vertical axis
  while it dollies in from 2.6 to 2.0 m and sinks from 0.3 to 0.15 m, so the silhouette
  sweeps across the image (about 2 px per frame at 320 px).
- sun-g0 / sun-g08: the sun climbs from 20 to 55 degrees while it turns 90 degrees in
  azimuth (0.8 degrees per frame), under the constant sky.
- sky-g06: the HDR daylight sky of bench/sky-sun.toml (its small sun carries most of the
  light; `nimbus make-sky target/bench/sky-sun.exr` writes it) turns 90 degrees about the
  vertical over 128 frames (0.7 degrees per frame): the paper's rotating environment map
  (Fig. 4, top).
- explosion-matched / explosion-mismatched: the emissive explosions of bench/ (fire
  coloured like its smoke's scattered light, and orange fire in bluish smoke) under the
  camera of camera-g0 (orbit and dolly): issue 26's explosions in motion, where each
  pixel's history is weak and the hue of its one selected path decides the error.

`nimbus study --per-frame` measures each frame against a reference of that frame (the
window after the longest warm-up, e.g. 80 frames for ReSTIR's default Q = 20); see
tools/gpu-check.sh and docs/restir.md. Re-run after changing the static benchmarks.
"""

import math
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
BENCH = ROOT / "assets/scenes/bench"
OUT = BENCH / "motion"
FRAMES = 128
STEP = 8


def fmt(v):
    return "[" + ", ".join(f"{x:.6f}" for x in v) + "]"


def medium_and_integrator(static):
    """The [[medium]] table onwards of a static benchmark scene."""
    text = (BENCH / static).read_text()
    return text[text.index("[[medium]]"):]


def header(title, lines):
    body = "\n".join(f"# {l}" if l else "#" for l in lines)
    return (
        f"# Motion benchmark (issue 26): {title}\n{body}\n"
        "# Written by tools/make_motion_bench.py; edit that, not this file.\n\n"
        f"[render]\nwidth = 320\nheight = 240\nframes = {FRAMES}\nseed = 3\n\n"
    )


SKY = '[[light]]\ntype = "environment"\nradiance = [0.25, 0.35, 0.55]\n\n'


def orbit_camera():
    """The [camera] of camera-g0: 40 degrees of orbit about the vertical axis while it
    dollies in from 2.6 to 2.0 m and sinks from 0.3 to 0.15 m, keyed every STEP frames."""
    out = "[camera]\nhorizontal_fov_deg = 55\n\n"
    for f in range(0, FRAMES + 1, STEP):
        t = f / FRAMES
        az = math.radians(40.0 * t)
        r = 2.6 - 0.6 * t
        y = 0.3 - 0.15 * t
        pos = (r * math.sin(az), y, r * math.cos(az))
        out += f"[[camera.keyframe]]\nframe = {f}\nposition = {fmt(pos)}\nlook_at = [0.0, 0.0, 0.0]\n\n"
    return out


def camera_scene(static, g_text):
    out = header(
        f"the camera orbits and dollies ({g_text}).",
        [
            "40 degrees of orbit about the vertical axis, 2.6 -> 2.0 m, over 128 frames:",
            "the silhouette sweeps the image by about 2 px per frame.",
        ],
    )
    out += orbit_camera()
    out += '[[light]]\ntype = "directional"\ndirection = [0.6, -0.5, -0.6]\nirradiance = [6.0, 5.6, 5.0]\n\n'
    out += SKY
    return out + medium_and_integrator(static)


def lights_of(static):
    """The [[light]] tables of a static benchmark scene (up to its [[medium]])."""
    text = (BENCH / static).read_text()
    return text[text.index("[[light]]"):text.index("[[medium]]")].rstrip() + "\n\n"


def explosion_scene(static, what):
    out = header(
        f"the {what} explosion under the orbiting camera.",
        [
            "The camera of camera-g0: 40 degrees of orbit, 2.6 -> 2.0 m, over 128 frames;",
            "the explosion's own sky lights it, its fire glows.",
        ],
    )
    out += orbit_camera()
    out += lights_of(static)
    return out + medium_and_integrator(static)


def sun_scene(static, g_text):
    out = header(
        f"the sun moves across the sky ({g_text}).",
        [
            "Elevation 20 -> 55 degrees and 90 degrees of azimuth over 128 frames",
            "(0.8 degrees per frame); the camera and the cloud hold still.",
        ],
    )
    out += "[camera]\nposition = [0.0, 0.3, 2.6]\nlook_at = [0.0, 0.0, 0.0]\nhorizontal_fov_deg = 55\n\n"
    out += '[[light]]\ntype = "directional"\nirradiance = [6.0, 5.6, 5.0]\n\n'
    for f in range(0, FRAMES + 1, STEP):
        t = f / FRAMES
        el = math.radians(20.0 + 35.0 * t)
        az = math.radians(-45.0 + 90.0 * t)
        to_sun = (math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az))
        travel = tuple(-c for c in to_sun)
        out += f"[[light.keyframe]]\nframe = {f}\ndirection = {fmt(travel)}\n\n"
    out += SKY
    return out + medium_and_integrator(static)


def sky_scene(static, g_text):
    out = header(
        f"the HDR sky turns about the vertical ({g_text}).",
        [
            "90 degrees over 128 frames (0.7 degrees per frame); the sky's small sun carries",
            "most of the light. Write the map first: nimbus make-sky target/bench/sky-sun.exr",
        ],
    )
    out += "[camera]\nposition = [0.0, 0.3, 2.6]\nlook_at = [0.0, 0.0, 0.0]\nhorizontal_fov_deg = 55\n\n"
    out += '[[light]]\ntype = "environment"\nfile = "../../../../target/bench/sky-sun.exr"\n\n'
    for f in range(0, FRAMES + 1, STEP):
        out += f"[[light.keyframe]]\nframe = {f}\nrotation_deg = {90.0 * f / FRAMES:.6f}\n\n"
    return out + medium_and_integrator(static)


def main():
    out = pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else OUT
    out.mkdir(parents=True, exist_ok=True)
    scenes = {
        "camera-g0.toml": camera_scene("cloud-g0.toml", "g = 0"),
        "camera-g08.toml": camera_scene("cloud-g08.toml", "g = 0.8"),
        "sun-g0.toml": sun_scene("cloud-g0.toml", "g = 0"),
        "sun-g08.toml": sun_scene("cloud-g08.toml", "g = 0.8"),
        "sky-g06.toml": sky_scene("sky-sun.toml", "g = 0.6"),
        "explosion-matched.toml": explosion_scene("explosion-matched.toml", "colour-matched"),
        "explosion-mismatched.toml": explosion_scene("explosion-mismatched.toml", "colour-mismatched"),
    }
    for name, text in scenes.items():
        (out / name).write_text(text)
        print(f"wrote {out / name}")


if __name__ == "__main__":
    main()
