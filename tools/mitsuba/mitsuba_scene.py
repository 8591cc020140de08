"""The benchmark cloud (assets/bench/perf-cloud.toml) as a Mitsuba 3 scene.

Conventions checked against Mitsuba 3.9.1's sources:
- volpath's max_depth counts path vertices: a medium scattering event j (1-based) gets
  next-event estimation and a phase-sampled continuation only while j < max_depth, and
  null-BSDF crossings do not count; so Nimbus's K scattering events = max_depth K + 1.
  rr_depth is set past any depth so Russian roulette never runs (Nimbus has none at K <= 3).
- directional `direction` is the direction light travels (emitter +z, sample_direction
  returns -d), `irradiance` is W/m^2 on a plane perpendicular to the beam: as Nimbus.
- gridvolume without use_grid_bbox spans the unit cube of its to_world (the .vol bbox
  0..1 is ignored), is trilinear with wrap_mode clamp, cell-centred (Dr.Jit textures
  sample at pos*res - 0.5): as Nimbus's grid medium. to_world maps it onto [-1,1]^3.
- heterogeneous `scale` multiplies the grid (sigma_t = 20 * density); a grey extinction,
  so has_spectral_extinction = False (volpath's cheaper non-spectral path).
- the perspective sensor's fov_axis 'x' is the horizontal field of view; box rfilter of
  radius 0.5 = Nimbus's box pixel filter (each sample lands in its own pixel).
"""

import mitsuba as mi

CAMERA_POS = [0.0, 0.2, 2.4]
LOOK_AT = [0.0, 0.0, 0.0]
FOV_X = 50.0
SUN_DIR = [0.6, -0.5, -0.6]
SUN_E = [6.0, 5.6, 5.0]
SKY_L = [0.25, 0.35, 0.55]
DENSITY_SCALE = 20.0
ALBEDO = 0.9


def scene_dict(vol_path, k, g, width=128, height=128):
    T = mi.ScalarTransform4f
    medium = {
        "type": "heterogeneous",
        "sigma_t": {
            "type": "gridvolume",
            "filename": vol_path,
            "filter_type": "trilinear",
            "wrap_mode": "clamp",
            "to_world": T().translate([-1.0, -1.0, -1.0]).scale(2.0),
        },
        "scale": DENSITY_SCALE,
        "albedo": ALBEDO,
        "has_spectral_extinction": False,
        "phase": {"type": "hg", "g": g} if g != 0.0 else {"type": "isotropic"},
    }
    return {
        "type": "scene",
        "integrator": {
            "type": "volpath",
            "max_depth": k + 1,
            "rr_depth": 100000,
        },
        "sensor": {
            "type": "perspective",
            "fov": FOV_X,
            "fov_axis": "x",
            "to_world": T().look_at(origin=CAMERA_POS, target=LOOK_AT, up=[0, 1, 0]),
            "sampler": {"type": "independent"},
            "film": {
                "type": "hdrfilm",
                "width": width,
                "height": height,
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
            },
        },
        "sun": {
            "type": "directional",
            "direction": SUN_DIR,
            "irradiance": {"type": "rgb", "value": SUN_E},
        },
        "sky": {"type": "constant", "radiance": {"type": "rgb", "value": SKY_L}},
        "cloud": {
            "type": "cube",
            "bsdf": {"type": "null"},
            "interior": medium,
        },
    }
