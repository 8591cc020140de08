//! The film's alpha: 1 − the camera ray's transmittance through every medium (1 where it
//! meets a surface or an emitter), checked against an independent f64 quadrature of the
//! grid's optical depth, and the transparent film: leaving out the environment that
//! camera rays see takes away exactly (1 − alpha) × the environment, so the image is the
//! premultiplied foreground a compositor lays over a plate.

use std::path::Path;

use nimbus::output::layers::{read_layers, Layers};
use nimbus_scene::{FieldOverride, Medium};

use crate::common::cli::{nimbus, text};

fn scratch(name: &str) -> std::path::PathBuf {
    crate::common::cli::scratch("alpha", name)
}

fn render(args: &[&str]) -> Layers {
    let out_at = args.iter().position(|a| *a == "--out").unwrap() + 1;
    let out = nimbus(&[&["render"], args].concat());
    assert!(out.status.success(), "{}", text(&out.stderr));
    read_layers(Path::new(args[out_at])).unwrap()
}

/// The window room (box medium, crepuscular pass, constant sky): the sky seen through the
/// window and the dusty air is T × sky per camera sample, with the same closed-form T as
/// alpha, so beauty − transparent = (1 − alpha) × sky to rounding.
#[test]
fn a_transparent_film_leaves_out_exactly_the_background_alpha_uncovers() {
    let dir = scratch("transparent");
    let (b, f) = (dir.join("beauty.exr"), dir.join("fore.exr"));
    let common = [
        "--width", "32", "--height", "24", "--frames", "2", "--spp", "2",
    ];
    let beauty = render(&[&common[..], &["--out", b.to_str().unwrap()]].concat());
    let fore = render(
        &[
            &common[..],
            &["--transparent", "--out", f.to_str().unwrap()],
        ]
        .concat(),
    );
    assert_eq!(beauty.alpha, fore.alpha);
    let sky = [0.45f32, 0.65, 1.0];
    let mut seen = 0;
    for (i, (bp, fp)) in beauty.color.data.iter().zip(&fore.color.data).enumerate() {
        let uncovered = 1.0 - beauty.alpha[i];
        if uncovered > 0.01 {
            seen += 1;
        }
        for c in 0..3 {
            let expected = uncovered * sky[c];
            let got = bp[c] - fp[c];
            assert!(
                (got - expected).abs() <= 1e-5 + 1e-4 * bp[c],
                "pixel {i} channel {c}: beauty − foreground {got} vs (1 − alpha) sky {expected}"
            );
        }
    }
    assert!(seen > 0, "no pixel sees the sky through the window");
}

/// A transparent render to a .png is RGBA with straight alpha: its alpha is the EXR's
/// to 8 bits (the window room: walls opaque, the sky through dusty air partly
/// transparent), a pixel of alpha 0 is black, and every pixel's colour is its
/// premultiplied colour divided by alpha, tonemapped.
#[test]
fn a_transparent_png_carries_the_alpha() {
    let dir = scratch("transparent-png");
    let (e, p) = (dir.join("fore.exr"), dir.join("fore.png"));
    let common = [
        "--width",
        "32",
        "--height",
        "24",
        "--frames",
        "2",
        "--spp",
        "2",
        "--transparent",
    ];
    let exr = render(&[&common[..], &["--out", e.to_str().unwrap()]].concat());
    let out = nimbus(&[&["render"], &common[..], &["--out", p.to_str().unwrap()]].concat());
    assert!(out.status.success(), "{}", text(&out.stderr));
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&p).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut bytes = vec![0u8; reader.output_buffer_size().unwrap()];
    let frame = reader.next_frame(&mut bytes).unwrap();
    assert_eq!(frame.color_type, png::ColorType::Rgba);
    assert_eq!((frame.width, frame.height), (32, 24));
    let straight = nimbus::output::ImageRgb {
        width: 32,
        height: 24,
        data: exr
            .color
            .data
            .iter()
            .zip(&exr.alpha)
            .map(|(c, &a)| {
                if a > 0.0 {
                    c.map(|v| v / a.min(1.0))
                } else {
                    [0.0; 3]
                }
            })
            .collect(),
    };
    let display = nimbus::output::Display {
        exposure: 1.0,
        tonemap: nimbus::output::Tonemap::Aces,
    };
    let rgb8 = nimbus::output::tonemap_srgb8_with(&straight, &display);
    // The window shows the sky through dusty air: those pixels are partly transparent.
    let (mut see_through, mut opaque) = (0, 0);
    for (i, px) in bytes.chunks_exact(4).enumerate() {
        let a = exr.alpha[i];
        assert_eq!(
            px[3],
            (a.clamp(0.0, 1.0) * 255.0).round() as u8,
            "pixel {i}"
        );
        assert_eq!(&px[..3], &rgb8[i][..], "pixel {i}");
        if px[3] == 0 {
            assert_eq!(&px[..3], &[0, 0, 0], "pixel {i}");
        }
        if px[3] < 255 {
            see_through += 1;
        } else {
            opaque += 1;
        }
    }
    assert!(
        see_through > 0 && opaque > 0,
        "{see_through} see-through, {opaque} opaque pixels"
    );
}

/// Alpha of the cloud (a 64x40x64 procedural grid) from the baseline and from ReSTIR,
/// pixel centres only, against 1 − exp(−∫σt) by the f64 midpoint rule along the same
/// camera rays (4000 steps through the grid: far finer than a voxel).
#[test]
fn alpha_is_one_minus_the_camera_rays_transmittance_through_the_grid() {
    let scene_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/cloud.toml");
    let (width, height) = (40u32, 30u32);
    let overrides = [
        FieldOverride::new("render.width", i64::from(width)),
        FieldOverride::new("render.height", i64::from(height)),
        FieldOverride::new("render.pixel_jitter", false),
    ];
    let scene = nimbus::load_scene(Some(&scene_path), &overrides).unwrap();
    let Medium::Grid(grid) = &scene.media[0] else {
        panic!("cloud.toml has a grid medium")
    };
    let density = nimbus_scene::load_grid(&grid.density, 1, "density").unwrap();
    let (lo, hi) = (grid.bounds_min.as_dvec3(), grid.bounds_max.as_dvec3());
    let dims = glam::DVec3::new(
        f64::from(density.dims[0]),
        f64::from(density.dims[1]),
        f64::from(density.dims[2]),
    );
    let camera = scene.camera.frame_at(0);
    let reference = |x: u32, y: u32| -> f64 {
        let o = camera.position.as_dvec3();
        let d = camera
            .ray_direction(x as f32 + 0.5, y as f32 + 0.5, width, height)
            .as_dvec3();
        // The ray's span inside the bounds (slab test).
        let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
        for a in 0..3 {
            let (ta, tb) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
        if t1 <= t0 {
            return 0.0;
        }
        let steps = 4000;
        let dt = (t1 - t0) / f64::from(steps);
        let mut tau = 0.0;
        for k in 0..steps {
            let p = o + (t0 + (f64::from(k) + 0.5) * dt) * d;
            let v = (p - lo) / (hi - lo) * dims;
            tau += density.sample_trilinear([v.x, v.y, v.z]) * dt;
        }
        1.0 - (-f64::from(grid.density_scale) * tau).exp()
    };

    let dir = scratch("grid");
    for volume in ["baseline", "restir"] {
        let path = dir.join(format!("{volume}.exr"));
        let layers = render(&[
            scene_path.to_str().unwrap(),
            "--width",
            "40",
            "--height",
            "30",
            "--frames",
            "1",
            "--set",
            "render.pixel_jitter=false",
            "--set",
            &format!("integrator.volume={volume}"),
            // cloud.toml takes 2 spp; ReSTIR draws one path per pixel per frame.
            "--spp",
            "1",
            "--out",
            path.to_str().unwrap(),
        ]);
        let mut worst = 0.0f64;
        let mut covered = 0;
        for y in (0..height).step_by(3) {
            for x in (0..width).step_by(3) {
                let got = f64::from(layers.alpha[(y * width + x) as usize]);
                let want = reference(x, y);
                worst = worst.max((got - want).abs());
                if want > 0.5 {
                    covered += 1;
                }
            }
        }
        println!("{volume}: largest |alpha − reference| {worst:.2e}, {covered} dense pixels");
        assert!(
            covered > 5,
            "{volume}: the cloud covers too few of the checked pixels"
        );
        assert!(
            worst < 2e-3,
            "{volume}: alpha off the quadrature by {worst}"
        );
        // The sky around the cloud is uncovered.
        assert_eq!(layers.alpha[0], 0.0, "{volume}: corner pixel");
    }
}
