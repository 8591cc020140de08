"""A Nimbus box-medium scene (box media, spheres, directional lights, a constant sky) as a
Mitsuba 3 scene dict, read from the same TOML file, so both renderers see one scene.

Conventions (besides those of mitsuba_scene.py, checked there against Mitsuba's sources):
- a Nimbus box medium is world = center + R * local, local in [-size/2, size/2], with
  R = Rz * Ry * Rx of `rotation_deg` (`rotation_xyz_deg`): Mitsuba's cube spans [-1, 1]^3,
  so its to_world is translate(center) * rotate(z) * rotate(y) * rotate(x) * scale(size/2);
  both rotate right-handed (counter-clockwise seen from the axis's tip).
- the box is a null-BSDF cube whose interior is a homogeneous medium (sigma_t, albedo,
  Henyey-Greenstein g); a sphere inside it is a diffuse sphere whose exterior is that
  medium, so paths leaving the sphere and its shadow rays stay in the fog.
- Nimbus's `max_bounces` K counts scatterings and reflections alike: volpath max_depth
  K + 1 (Russian roulette off; Nimbus has none before its 4th segment).
Anything else in the scene file (surfaces other than spheres, other lights, grid media,
gobos) is refused rather than dropped.
"""

import tomllib

import mitsuba as mi


def _refuse(path, what):
    raise SystemExit("box_scene.py: %s: %s is not translated to Mitsuba" % (path, what))


def load_toml(path):
    with open(path, "rb") as f:
        return tomllib.load(f)


def scene_dict(path, k, overrides=None):
    """The scene at `path` as a Mitsuba dict, with K = k. `overrides`: {"width", "height"}."""
    s = load_toml(path)
    T = mi.ScalarTransform4f
    render = dict(s.get("render", {}), **(overrides or {}))
    cam = s["camera"]
    up = cam.get("up", [0.0, 1.0, 0.0])
    d = {
        "type": "scene",
        "integrator": {"type": "volpath", "max_depth": k + 1, "rr_depth": 100000},
        "sensor": {
            "type": "perspective",
            "fov": cam["horizontal_fov_deg"],
            "fov_axis": "x",
            "to_world": T().look_at(origin=cam["position"], target=cam["look_at"], up=up),
            "sampler": {"type": "independent"},
            "film": {
                "type": "hdrfilm",
                "width": render.get("width", 320),
                "height": render.get("height", 240),
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
            },
        },
    }
    for key in cam:
        if key not in ("position", "look_at", "horizontal_fov_deg", "up"):
            _refuse(path, "camera." + key)

    for i, light in enumerate(s.get("light", [])):
        kind = light["type"]
        if kind == "directional":
            for key in light:
                if key not in ("type", "direction", "irradiance"):
                    _refuse(path, "light.%d.%s" % (i + 1, key))
            d["light%d" % i] = {"type": "directional", "direction": light["direction"],
                                "irradiance": {"type": "rgb", "value": light["irradiance"]}}
        elif kind == "environment":
            for key in light:
                if key not in ("type", "radiance"):
                    _refuse(path, "light.%d.%s" % (i + 1, key))
            d["light%d" % i] = {"type": "constant", "radiance": {"type": "rgb", "value": light["radiance"]}}
        else:
            _refuse(path, "light.%d (%s)" % (i + 1, kind))

    media = s.get("medium", [])
    boxes = []
    for i, m in enumerate(media):
        if m["type"] != "box":
            _refuse(path, "medium.%d (%s)" % (i + 1, m["type"]))
        for key in m:
            if key not in ("type", "center", "size", "rotation_deg", "sigma_t", "albedo", "g"):
                _refuse(path, "medium.%d.%s" % (i + 1, key))
        g = m.get("g", 0.0)
        mid = "fog%d" % i
        d[mid] = {
            "type": "homogeneous",
            "sigma_t": m["sigma_t"],
            "albedo": m.get("albedo", 1.0),
            "phase": {"type": "hg", "g": g} if g != 0.0 else {"type": "isotropic"},
        }
        r = m.get("rotation_deg", [0.0, 0.0, 0.0])
        half = [x / 2 for x in m["size"]]
        to_world = (T().translate(m["center"]).rotate([0, 0, 1], r[2]).rotate([0, 1, 0], r[1])
                    .rotate([1, 0, 0], r[0]).scale(half))
        d["box%d" % i] = {"type": "cube", "to_world": to_world, "bsdf": {"type": "null"},
                          "interior": {"type": "ref", "id": mid}}
        boxes.append((m, mid))

    for i, shape in enumerate(s.get("shape", [])):
        if shape["type"] != "sphere":
            _refuse(path, "shape.%d (%s)" % (i + 1, shape["type"]))
        for key in shape:
            if key not in ("type", "center", "radius", "albedo"):
                _refuse(path, "shape.%d.%s" % (i + 1, key))
        sph = {"type": "sphere", "center": shape["center"], "radius": shape["radius"],
               "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": _rgb(shape.get("albedo", 0.5))}}}
        inside = [mid for m, mid in boxes if _sphere_in_box(shape, m)]
        if len(inside) > 1 or (not inside and any(_sphere_meets_box(shape, m) for m, _ in boxes)):
            _refuse(path, "shape.%d (a sphere that crosses a medium's boundary)" % (i + 1))
        if inside:
            sph["exterior"] = {"type": "ref", "id": inside[0]}
        d["shape%d" % i] = sph

    for key in s.get("integrator", {}):
        if key not in ("box_estimator", "box_samples", "max_bounces"):
            _refuse(path, "integrator." + key)
    return d


def _rgb(v):
    return v if isinstance(v, list) else [v, v, v]


def _local(p, m):
    import numpy as np
    r = np.radians(m.get("rotation_deg", [0.0, 0.0, 0.0]))
    cx, cy, cz = np.cos(r)
    sx, sy, sz = np.sin(r)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    rot = rz @ ry @ rx
    return rot.T @ (np.array(p, dtype=float) - np.array(m["center"], dtype=float))


def _sphere_in_box(shape, m):
    q = _local(shape["center"], m)
    return all(abs(q[a]) + shape["radius"] <= m["size"][a] / 2 for a in range(3))


def _sphere_meets_box(shape, m):
    q = _local(shape["center"], m)
    nearest = [max(-m["size"][a] / 2, min(q[a], m["size"][a] / 2)) for a in range(3)]
    return sum((q[a] - nearest[a]) ** 2 for a in range(3)) < shape["radius"] ** 2
