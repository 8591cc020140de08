#!/usr/bin/env python3
"""Writes the .vdb test files for Nimbus's OpenVDB reader, with OpenVDB itself.

Usage: make_test_vdbs.py OUT_DIR [--committed]

Needs Debian's python3-openvdb (pyopenvdb, OpenVDB 10) and, for the zip / "active" /
uncompressed variants, vdb_tool from libopenvdb-tools (both installed by
tools/install-deps.sh). pyopenvdb writes Blosc files; vdb_tool re-encodes them
(`-write codec=zip|active|none`).

The expected contents are what OpenVDB reads back from each written file, not what
was asked for: after writing, every grid is read again with pyopenvdb and its active
values are dumped (`citerOnValues`: single voxels and tiles alike) to
`items-<hash>.bin`, records of little-endian i32 min[3], i32 max[3] (inclusive),
f32 value[channels]. OUT_DIR/manifest.json describes each file:

  {"files": [{"file": "float_blosc.vdb", "codec": "blosc",
              "grids": [{"name", "type" ("float" | "vec3s" | "bool"), "saved_as_half",
                         "class", "map_type", "index_to_world" (4 columns of 4),
                         "background" [channels], "active_voxels", "bbox" [[min], [max]]
                         or null, "leaf_count", "items", "item_count"}]},
             {"file": "nan.vdb", "error": "substring of the expected error",
              "grid": name or null, "kind": "scalar" | "vec3" | "any"}]}

--committed writes only the compact cases kept in assets/test-vdb/ (a few small
files: Blosc, zip, half, vec3, tiles, several grids, a level set).
"""
import hashlib
import json
import math
import os
import shutil
import struct
import subprocess
import sys

import numpy as np
import pyopenvdb as vdb


def sphere_values(channels):
    """A ball of about 250 active voxels around (-1, 6, 9), crossing index 0 in x only
    (two root children: negative and positive coordinates, files of ~20 KB), values
    exact in float32."""
    origin = (-6, 1, 4)
    shape = (11, 11, 11)
    arr = np.zeros(shape + ((channels,) if channels > 1 else ()), dtype=np.float32)
    for a in range(shape[0]):
        for b in range(shape[1]):
            for c in range(shape[2]):
                i, j, k = a + origin[0], b + origin[1], c + origin[2]
                if (i + 1) ** 2 + (j - 6) ** 2 + (k - 9) ** 2 > 15:
                    continue
                base = (i * 7 + j * 13 + k * 29) % 97 + 1
                if channels == 1:
                    arr[a, b, c] = base / 97.0
                else:
                    arr[a, b, c] = (base / 97.0, (base % 5) - 2.5, -(base / 13.0))
    return origin, arr


def sphere_grid(name, channels=1, half=False):
    grid = vdb.Vec3SGrid() if channels == 3 else vdb.FloatGrid()
    origin, arr = sphere_values(channels)
    grid.copyFromArray(arr, ijk=origin, tolerance=(0, 0, 0) if channels == 3 else 0)
    grid.name = name
    grid.saveFloatAsHalf = half
    return grid


def affine_transform():
    """Non-uniform scale, rotation about two axes, translation: an AffineMap."""
    t = vdb.createLinearTransform([[0.5, 0, 0, 0], [0, 0.25, 0, 0], [0, 0, 0.75, 0], [0, 0, 0, 1]])
    t.rotate(0.3, vdb.Axis.Y)
    t.rotate(-1.1, vdb.Axis.Z)
    t.translate((1.5, -2.0, 30.25))
    return t


def scale_translate_transform():
    t = vdb.createLinearTransform()
    t.scale((0.5, 2.0, 1.25))
    t.translate((-3.0, 4.5, 0.125))
    return t


def uniform_scale_translate_transform():
    t = vdb.createLinearTransform(0.125)
    t.translate((10.0, 0.0, -7.5))
    return t


def scale_transform():
    t = vdb.createLinearTransform()
    t.scale((2.0, 3.0, 0.5))
    return t


def tiles_grid():
    """Tiles at both internal levels, a partial leaf, and voxels far apart (the bbox is
    thousands of voxels wide, the grid a handful of bricks)."""
    grid = vdb.FloatGrid()
    grid.name = "density"
    grid.fill((0, 0, 0), (127, 127, 127), 0.25)  # a 128³ tile of a 32³ node
    grid.fill((128, 0, 0), (135, 7, 7), 0.5)  # an 8³ tile of a 16³ node
    grid.fill((128, 8, 0), (131, 9, 1), 0.75)  # voxels of one leaf
    acc = grid.getAccessor()
    acc.setValueOn((3000, -2000, 1500), 1.0)
    acc.setValueOn((-5000, 4100, -9000), 2.0)
    acc.setValueOn((-5001, 4100, -9000), 3.0)
    grid.transform = vdb.createLinearTransform(0.1)
    return grid


def inactive_modes_grid():
    """Leaves whose inactive voxels hold other values than the background (0.1), one
    leaf per per-node mask-compression mode of io/Compression.h: 0 (all background),
    1 (all -background), 2 (one other value), 3 (mask: -background / background),
    4 (mask: background / one other), 5 (mask: two others), 6 (more: all stored)."""
    grid = vdb.FloatGrid(0.1)
    grid.name = "density"
    leaves = [
        [],
        [(0, 7, -0.1)],
        [(0, 7, 0.3)],
        [(0, 3, -0.1)],
        [(0, 3, 0.3)],
        [(0, 3, 0.3), (4, 7, 0.6)],
        [(0, 1, 0.3), (2, 3, 0.6), (4, 5, 0.9)],
    ]
    for n, fills in enumerate(leaves):
        x0 = 8 * n
        for lo, hi, value in fills:
            grid.fill((x0 + lo, 0, 0), (x0 + hi, 7, 7), value, False)
        acc = grid.getAccessor()
        acc.setValueOn((x0 + 1, 2, 3), 1.0 + n)
        acc.setValueOn((x0 + 6, 5, 4), 2.0 + n)
    return grid


def small_grid(name, value, at):
    grid = vdb.FloatGrid()
    grid.name = name
    grid.fill(at, (at[0] + 2, at[1] + 1, at[2] + 3), value)
    return grid


def vdb_tool(src, dst, codec, half=False):
    args = ["vdb_tool", "-quiet", "-read", src, "-write", f"codec={codec}"]
    if half:
        args.append("bits=16")
    subprocess.run(args + [dst], check=True, stdout=subprocess.DEVNULL)


def grid_type(grid):
    return {"FloatGrid": "float", "Vec3SGrid": "vec3s", "BoolGrid": "bool"}[type(grid).__name__]


def dump_grid(grid, out_dir):
    """Manifest entry and item records for a grid as OpenVDB read it back."""
    gtype = grid_type(grid)
    channels = 3 if gtype == "vec3s" else 1
    records = bytearray()
    count = 0
    for item in grid.citerOnValues():
        value = item.value
        values = list(value) if channels == 3 else [float(value)]
        records += struct.pack("<6i", *item.min, *item.max)
        records += struct.pack(f"<{channels}f", *values)
        count += 1
    name = f"items-{hashlib.sha1(bytes(records)).hexdigest()[:12]}.bin"
    with open(os.path.join(out_dir, name), "wb") as f:
        f.write(records)
    t = grid.transform
    o = t.indexToWorld((0, 0, 0))
    cols = [[t.indexToWorld(e)[r] - o[r] for r in range(3)] + [0.0] for e in ((1, 0, 0), (0, 1, 0), (0, 0, 1))]
    cols.append(list(o) + [1.0])
    bbox = grid.evalActiveVoxelBoundingBox()
    bg = grid.background
    return {
        "name": grid.name,
        "type": gtype,
        "saved_as_half": bool(grid.saveFloatAsHalf),
        "class": str(grid.gridClass),
        "map_type": t.typeName,
        "index_to_world": cols,
        "background": list(bg) if channels == 3 else [float(bg)],
        "active_voxels": grid.activeVoxelCount(),
        "bbox": [list(bbox[0]), list(bbox[1])] if grid.activeVoxelCount() > 0 else None,
        "leaf_count": grid.leafCount(),
        "items": name,
        "item_count": count,
    }


def main():
    out_dir = sys.argv[1]
    committed = "--committed" in sys.argv[2:]
    os.makedirs(out_dir, exist_ok=True)
    have_tool = shutil.which("vdb_tool") is not None
    files = []

    def path(name):
        return os.path.join(out_dir, name)

    def good(name, codec, grids=None, src=None, half=False):
        """Writes `grids` (Blosc, pyopenvdb's default) or re-encodes `src` with vdb_tool."""
        if grids is not None:
            vdb.write(path(name), grids=grids)
        else:
            if not have_tool:
                print(f"make_test_vdbs: no vdb_tool, skipping {name}", file=sys.stderr)
                return
            vdb_tool(path(src), path(name), codec, half)
        read_back = vdb.readAll(path(name))[0]
        entry = {"file": name, "codec": codec, "grids": [dump_grid(g, out_dir) for g in read_back]}
        files.append(entry)

    def bad(name, error, grids=None, grid=None, kind="scalar", make=None):
        if make is not None:
            make(path(name))
        else:
            vdb.write(path(name), grids=grids)
        files.append({"file": name, "error": error, "grid": grid, "kind": kind})

    # Floats: Blosc (pyopenvdb's default), zip, mask compression only, none.
    g = sphere_grid("density")
    g.transform = affine_transform()
    good("float_blosc.vdb", "blosc", grids=[g])
    if not committed:
        good("float_zip.vdb", "zip", src="float_blosc.vdb")
        good("float_active.vdb", "active", src="float_blosc.vdb")
        good("float_none.vdb", "none", src="float_blosc.vdb")

    # Half floats with other transforms.
    g = sphere_grid("density", half=True)
    g.transform = scale_translate_transform()
    vdb.write(path("half_src.vdb"), grids=[g])
    good("half_zip.vdb", "zip", src="half_src.vdb")
    if not committed:
        good("half_blosc.vdb", "blosc", src="half_src.vdb")
        good("half_none.vdb", "none", src="half_src.vdb")
        g = sphere_grid("density", half=True)
        g.transform = uniform_scale_translate_transform()
        good("half_blosc_ust.vdb", "blosc", grids=[g])
    os.remove(path("half_src.vdb"))

    # Vectors.
    g = sphere_grid("vel", channels=3)
    g.transform = uniform_scale_translate_transform()
    good("vec3_blosc.vdb", "blosc", grids=[g])
    if not committed:
        good("vec3_half_active.vdb", "active", src="vec3_blosc.vdb", half=True)
        good("vec3_zip.vdb", "zip", src="vec3_blosc.vdb")

    # Tiles and far-apart voxels.
    good("tiles_blosc.vdb", "blosc", grids=[tiles_grid()])
    if not committed:
        good("tiles_zip.vdb", "zip", src="tiles_blosc.vdb")
        good("tiles_none.vdb", "none", src="tiles_blosc.vdb")

    good("inactive_modes_blosc.vdb", "blosc", grids=[inactive_modes_grid()])
    if not committed:
        good("inactive_modes_none.vdb", "none", src="inactive_modes_blosc.vdb")

    # Several grids in one file, one of them a bool grid; one float grid instancing another.
    dens = small_grid("density", 0.5, (1, 2, 3))
    dens.gridClass = vdb.GridClass.FOG_VOLUME  # as Houdini, Blender and EmberGen write density
    temp = small_grid("temperature", 300.0, (4, 5, 6))
    temp.transform = scale_transform()
    vel = vdb.Vec3SGrid()
    vel.name = "vel"
    vel.fill((0, 0, 0), (1, 2, 3), (1.0, -2.0, 0.5))
    mask = vdb.BoolGrid()
    mask.name = "mask"
    mask.fill((0, 0, 0), (3, 3, 3), True)
    inst = dens.copy()  # shares dens's tree: written as an instance
    inst.name = "density_copy"
    good("multi.vdb", "blosc", grids=[dens, temp, vel, mask, inst])

    # A level set: inactive values are -background inside, +background outside, which
    # exercises the mask-compression modes with a selection mask.
    ls = vdb.createLevelSetSphere(radius=1.5, center=(6.3, 6.2, 6.1), voxelSize=0.5, halfWidth=2.0)
    ls.name = "surface"
    good("levelset_blosc.vdb", "blosc", grids=[ls])

    if not committed:
        # Errors.
        g = small_grid("density", 1.0, (0, 0, 0))
        g.getAccessor().setValueOn((5, 6, 7), float("nan"))
        bad("nan.vdb", "voxel [5, 6, 7] is NaN", grids=[g])
        g = small_grid("density", 1.0, (0, 0, 0))
        g.getAccessor().setValueOn((-3, 2, 1), float("inf"))
        bad("inf.vdb", "voxel [-3, 2, 1] is inf", grids=[g])
        g = small_grid("density", 1.0, (0, 0, 0))
        g.transform = vdb.createFrustumTransform(
            xyzMin=(0, 0, 0), xyzMax=(10, 10, 10), taper=0.5, depth=5.0, voxelSize=1.0
        )
        bad("frustum.vdb", "NonlinearFrustumMap", grids=[g])
        m = vdb.BoolGrid()
        m.name = "mask"
        m.fill((0, 0, 0), (3, 3, 3), True)
        bad("bool_only.vdb", "no scalar grid", grids=[m])
        bad("bool_named.vdb", "it holds bool values", grids=[m], grid="mask")
        bad("vec3_as_scalar.vdb", "it holds vec3s values", grids=[sphere_grid("vel", 3)], grid="vel")
        bad("scalar_as_vec3.vdb", "it holds float values", grids=[small_grid("d", 1.0, (0, 0, 0))], grid="d", kind="vec3")
        bad("missing_grid.vdb", 'no grid named "smoke"; the file has grids: density (float), vel (vec3s)',
            grids=[small_grid("density", 1.0, (0, 0, 0)), vel], grid="smoke")
        bad("two_floats.vdb", 'none named "density"',
            grids=[small_grid("a", 1.0, (0, 0, 0)), small_grid("b", 1.0, (0, 0, 0))])
        g = vdb.FloatGrid()
        g.name = "density"
        g.fill((0, 0, 0), (4095, 4095, 4095), 1.0)  # one active root tile: 2^36 voxels
        bad("root_tile.vdb", "over the limit of 2^31", grids=[g])
        if have_tool:
            def stream(dst):
                with open(dst, "wb") as f:
                    subprocess.run(
                        ["vdb_tool", "-quiet", "-read", path("float_blosc.vdb"), "-write", "stdout.vdb"],
                        check=True, stdout=f)
            bad("stream.vdb", "no grid offsets", make=stream)

    with open(os.path.join(out_dir, "manifest.json"), "w") as f:
        json.dump({"files": files}, f, indent=1)
    print(f"make_test_vdbs: {len(files)} files in {out_dir}")


if __name__ == "__main__":
    main()
