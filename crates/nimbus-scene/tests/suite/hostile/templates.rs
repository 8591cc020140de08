//! The hostile suite's minimal scenes: one valid scene per table of the contract
//! (`docs/scene-format.md`), the inline tables described in prose, and the directory of
//! valid and hostile files they name.

use std::path::{Path, PathBuf};

use crate::common::TempDir;

/// A step from a table to a sub-table: a key, or the N-th (from 0) entry of an array of
/// tables.
#[derive(Clone, Copy, Debug)]
pub(super) enum Step {
    Key(&'static str),
    Index(usize),
}
pub(super) use Step::{Index, Key};

/// A minimal valid scene holding one table of the contract.
pub(super) struct Template {
    /// The `### ...` heading of docs/scene-format.md it covers.
    pub(super) section: &'static str,
    /// The scene after `[camera]`, which every template starts with.
    pub(super) text: String,
    /// Where the table sits in the scene.
    pub(super) path: Vec<Step>,
    /// What every refusal's message must contain to name the table (`None`: the top
    /// level, which the contract does not name).
    pub(super) table: Option<&'static str>,
}

/// Where the test's files live: the scene is parsed as `dir/scene.toml`, so its
/// relative file names resolve there. The directory is removed on drop.
pub(super) struct Files {
    pub(super) _dir: TempDir,
    pub(super) scene: PathBuf,
}

pub(super) fn asset(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets/test-vdb")
        .join(name)
        .canonicalize()
        .expect("test vdb")
        .display()
        .to_string()
}

impl Files {
    pub(super) fn new() -> Self {
        let dir = TempDir::new("hostile");
        // Valid inputs the templates name.
        let ones: Vec<u8> = [1.0f32; 8].iter().flat_map(|v| v.to_le_bytes()).collect();
        dir.write("ones.raw", &ones);
        dir.write("vel.raw", &[0u8; 8 * 3 * 4]);
        dir.write("tri.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        let sky = dir.0.join("sky.exr");
        exr::prelude::write_rgb_file(&sky, 4, 2, |_, _| (1.0f32, 1.0f32, 1.0f32)).unwrap();
        // Hostile files: for every extension the format reads, an empty file, a
        // directory and a link to a device that never ends.
        for ext in EXTENSIONS {
            dir.write(&format!("empty{ext}"), b"");
            std::fs::create_dir_all(dir.0.join(format!("dir{ext}"))).unwrap();
            #[cfg(unix)]
            std::os::unix::fs::symlink("/dev/zero", dir.0.join(format!("zero{ext}"))).unwrap();
        }
        let scene = dir.0.join("scene.toml");
        Self { _dir: dir, scene }
    }
}

pub(super) const EXTENSIONS: &[&str] = &["", ".raw", ".vol", ".exr", ".obj", ".ply", ".vdb"];

pub(super) const CAMERA: &str = "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n";
pub(super) const RENDER: &str = "[render]\nwidth = 8\nheight = 8\nframes = 3\n";

/// One minimal scene per section of the contract (some sections get several: each light
/// type's keyframes, a grid source as file, procedural, emission and velocity).
pub(super) fn templates() -> Vec<Template> {
    let t = |section, text: &str, path: Vec<Step>, table| Template {
        section,
        text: text.to_string(),
        path,
        table,
    };
    let multi = asset("multi.vdb");
    let vdb = format!(
        "[[medium]]\ntype = \"vdb\"\ndensity = {{ file = \"{multi}\", grid = \"density\" }}\n\
         emission = {{ file = \"{multi}\", grid = \"density_copy\" }}\n\
         velocity = {{ file = \"{multi}\", grid = \"vel\" }}\n\
         to_world = {{ scale = 0.1, rotate_deg = [0, 30, 0], translate = [0, 0, -20] }}\n\
         [[medium.frame]]\nframe = 1\ndensity = {{ file = \"{multi}\", grid = \"density_copy\" }}\n"
    );
    let grid = "[[medium]]\ntype = \"grid\"\nbounds_min = [-1, -1, -1]\nbounds_max = [1, 1, 1]\n\
                density = { file = \"ones.raw\", dims = [2, 2, 2] }\n\
                emission = { procedural = \"cloud\", dims = [4, 4, 4] }\n\
                velocity = { file = \"vel.raw\", dims = [2, 2, 2] }\n\
                [[medium.frame]]\nframe = 1\ndensity = { procedural = \"cloud\", dims = [4, 4, 4], noise_seed = 3 }\n";
    let procedural =
        "[[medium]]\ntype = \"grid\"\nbounds_min = [-1, -1, -1]\nbounds_max = [1, 1, 1]\n\
                      density = { procedural = \"cloud\", dims = [4, 4, 4] }\n";
    let cube_planes = "planes = [[1, 0, 0, 1], [-1, 0, 0, 1], [0, 1, 0, 1], [0, -1, 0, 1], [0, 0, 1, 1], [0, 0, -1, 1]]";
    let light0 = || vec![Key("light"), Index(0)];
    let key0 = || vec![Key("light"), Index(0), Key("keyframe"), Index(0)];
    let medium0 = || vec![Key("medium"), Index(0)];
    let shape0 = || vec![Key("shape"), Index(0)];
    vec![
        t("top level", "", vec![], None),
        t("[render]", RENDER, vec![Key("render")], Some("[render]")),
        t("[camera]", "", vec![Key("camera")], Some("[camera]")),
        t(
            "[[camera.keyframe]]",
            "[[camera.keyframe]]\nframe = 0\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n\
             [[camera.keyframe]]\nframe = 2\nposition = [1, 0, 5]\nlook_at = [0, 0, 0]\n",
            vec![Key("camera"), Key("keyframe"), Index(0)],
            Some("[[camera.keyframe]]"),
        ),
        t(
            "[[light]] type = \"directional\"",
            "[[light]]\ntype = \"directional\"\ndirection = [0.2, -1, 0]\nirradiance = 2\n\
             gobo = [[0, 0], [1, 0], [0, 1]]\ngobo_origin = [0, 1, 0]\n",
            light0(),
            Some("[[light]] #1"),
        ),
        t(
            "[[light]] type = \"directional\"",
            "[[light]]\ntype = \"directional\"\ndirection = [0.2, -1, 0]\nirradiance = 2\n",
            light0(),
            Some("[[light]] #1"),
        ),
        t(
            "[[light]] type = \"environment\"",
            "[[light]]\ntype = \"environment\"\nradiance = 1\nscale = [1, 0.5, 0.25]\n",
            light0(),
            Some("[[light]] #1"),
        ),
        t(
            "[[light]] type = \"environment\"",
            "[[light]]\ntype = \"environment\"\nfile = \"sky.exr\"\nrotation_deg = -30\n",
            light0(),
            Some("[[light]] #1"),
        ),
        t(
            "[[light]] type = \"point\"",
            "[[light]]\ntype = \"point\"\nposition = [0, 3, 0]\nintensity = 1\n",
            light0(),
            Some("[[light]] #1"),
        ),
        t(
            "[[light]] type = \"sphere\"",
            "[[light]]\ntype = \"sphere\"\ncenter = [0, 3, 0]\nradius = 0.5\nradiance = 1\n",
            light0(),
            Some("[[light]] #1"),
        ),
        t(
            "[[light.keyframe]] of a \"directional\" light",
            &format!(
                "{RENDER}[[light]]\ntype = \"directional\"\ndirection = [0.2, -1, 0]\nirradiance = 2\n\
                 [[light.keyframe]]\nframe = 0\ndirection = [0, -1, 0]\nirradiance = 1\n\
                 [[light.keyframe]]\nframe = 2\ndirection = [0.5, -1, 0]\n"
            ),
            key0(),
            Some("[[light.keyframe]]"),
        ),
        t(
            "[[light.keyframe]] of an \"environment\" light",
            &format!(
                "{RENDER}[[light]]\ntype = \"environment\"\nfile = \"sky.exr\"\nrotation_deg = 10\n\
                 [[light.keyframe]]\nframe = 0\nrotation_deg = 350\n\
                 [[light.keyframe]]\nframe = 2\n"
            ),
            key0(),
            Some("[[light.keyframe]]"),
        ),
        t(
            "[[light.keyframe]] of a \"point\" light",
            &format!(
                "{RENDER}[[light]]\ntype = \"point\"\nposition = [0, 3, 0]\nintensity = 1\n\
                 [[light.keyframe]]\nframe = 0\nposition = [0, 3, 0]\nintensity = 1\n\
                 [[light.keyframe]]\nframe = 2\nposition = [1, 3, 0]\n"
            ),
            key0(),
            Some("[[light.keyframe]]"),
        ),
        t(
            "[[light.keyframe]] of a \"sphere\" light",
            &format!(
                "{RENDER}[[light]]\ntype = \"sphere\"\ncenter = [0, 3, 0]\nradius = 0.5\nradiance = 1\n\
                 [[light.keyframe]]\nframe = 0\ncenter = [0, 3, 0]\nradiance = 1\n\
                 [[light.keyframe]]\nframe = 2\ncenter = [1, 3, 0]\n"
            ),
            key0(),
            Some("[[light.keyframe]]"),
        ),
        t(
            "[[medium]] type = \"box\"",
            "[[medium]]\ntype = \"box\"\ncenter = [0, 0, 0]\nsize = [1, 2, 1]\nrotation_deg = [0, 30, 0]\n\
             sigma_t = 1\nalbedo = 0.5\ng = 0.3\n",
            medium0(),
            Some("[[medium]] #1"),
        ),
        t(
            "[[medium]] type = \"convex\"",
            &format!("[[medium]]\ntype = \"convex\"\n{cube_planes}\nsigma_t = 1\n"),
            medium0(),
            Some("[[medium]] #1"),
        ),
        t("[[medium]] type = \"grid\"", grid, medium0(), Some("[[medium]] #1")),
        t(
            "[[medium]] type = \"grid\"",
            procedural,
            medium0(),
            Some("[[medium]] #1"),
        ),
        t(
            "grid source",
            grid,
            vec![Key("medium"), Index(0), Key("density")],
            Some("[[medium]] #1 (type = \"grid\") > density"),
        ),
        t(
            "grid source",
            grid,
            vec![Key("medium"), Index(0), Key("emission")],
            Some("[[medium]] #1 (type = \"grid\") > emission"),
        ),
        t(
            "grid source",
            grid,
            vec![Key("medium"), Index(0), Key("velocity")],
            Some("[[medium]] #1 (type = \"grid\") > velocity"),
        ),
        t(
            "grid source",
            grid,
            vec![
                Key("medium"),
                Index(0),
                Key("frame"),
                Index(0),
                Key("density"),
            ],
            Some("[[medium.frame]] #1 > density"),
        ),
        t(
            "[[medium.frame]]",
            grid,
            vec![Key("medium"), Index(0), Key("frame"), Index(0)],
            Some("[[medium.frame]] #1"),
        ),
        t(
            "[[medium.frame]]",
            &vdb,
            vec![Key("medium"), Index(0), Key("frame"), Index(0)],
            Some("[[medium.frame]] #1"),
        ),
        t("[[medium]] type = \"vdb\"", &vdb, medium0(), Some("[[medium]] #1")),
        t(
            "[[shape]] type = \"quad\"",
            "[[shape]]\ntype = \"quad\"\ncorner = [-1, -1, 0]\nedge_u = [2, 0, 0]\nedge_v = [0, 2, 0]\n\
             albedo = 0.5\nemission = 1\n",
            shape0(),
            Some("[[shape]] #1"),
        ),
        t(
            "[[shape]] type = \"box\"",
            "[[shape]]\ntype = \"box\"\ncenter = [0, 0, 0]\nsize = [1, 1, 1]\nrotation_deg = [10, 0, 0]\n\
             albedo = 0.5\n",
            shape0(),
            Some("[[shape]] #1"),
        ),
        t(
            "[[shape]] type = \"sphere\"",
            "[[shape]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nalbedo = 0.5\n",
            shape0(),
            Some("[[shape]] #1"),
        ),
        t(
            "[[shape]] type = \"mesh\"",
            "[[shape]]\ntype = \"mesh\"\nfile = \"tri.obj\"\nto_world = { scale = 2, rotate_deg = [0, 90, 0], translate = [0, 1, 0] }\nalbedo = 0.5\n",
            shape0(),
            Some("[[shape]] #1"),
        ),
        t(
            "[integrator]",
            "[integrator]\nmax_bounces = 2\n",
            vec![Key("integrator")],
            Some("[integrator]"),
        ),
        t(
            "[integrator.restir]",
            &format!("{procedural}[integrator.restir]\ncandidates = 2\n"),
            vec![Key("integrator"), Key("restir")],
            Some("[integrator.restir]"),
        ),
        t(
            "[integrator.baseline]",
            &format!("{procedural}[integrator.baseline]\nnee = \"one\"\n"),
            vec![Key("integrator"), Key("baseline")],
            Some("[integrator.baseline]"),
        ),
    ]
}

/// Inline tables the contract describes in prose rather than in a field table: the
/// `{ file, grid }` of a vdb medium and the `to_world` of vdb media and meshes. Their
/// fields are listed here, and get the same values.
pub(super) fn inline_templates() -> Vec<(Template, Vec<&'static str>)> {
    let all = templates();
    let find = |section: &str| {
        all.iter()
            .find(|t| t.section == section)
            .unwrap()
            .text
            .clone()
    };
    let vdb = find("[[medium]] type = \"vdb\"");
    let mesh = find("[[shape]] type = \"mesh\"");
    let to_world = vec!["scale", "rotate_deg", "translate"];
    let mut out = Vec::new();
    for key in ["density", "emission", "velocity"] {
        out.push((
            Template {
                section: "vdb grid table",
                text: vdb.clone(),
                path: vec![Key("medium"), Index(0), Key(key)],
                table: Some("[[medium]] #1"),
            },
            vec!["file", "grid"],
        ));
    }
    out.push((
        Template {
            section: "vdb to_world",
            text: vdb,
            path: vec![Key("medium"), Index(0), Key("to_world")],
            table: Some("[[medium]] #1 (type = \"vdb\") > to_world"),
        },
        to_world.clone(),
    ));
    out.push((
        Template {
            section: "mesh to_world",
            text: mesh,
            path: vec![Key("shape"), Index(0), Key("to_world")],
            table: Some("[[shape]] #1 (type = \"mesh\") > to_world"),
        },
        to_world,
    ));
    out
}
