//! Offscreen rendering checked against the core: the vertices the shader computes equal
//! `World::current_vertices`, and the picture shows each body in its colour where the core's
//! geometry says it is visible, and the background where nothing is.
//!
//! Needs a wgpu adapter (a software one such as lavapipe will do). Without one the tests print
//! why and pass, unless TUMBLE_REQUIRE_GPU=1, which makes them fail.
#![cfg(feature = "viewer")]

use glam::DVec3;
use tumble::viewer::palette;
use tumble::viewer::picking::pick;
use tumble::viewer::{DrawOptions, Image, OffscreenRenderer, OrbitCamera};
use tumble::{ConstraintsChoice, Settings, World};

fn load(scene: &str) -> World {
    tumble::scene::load(scene, &ConstraintsChoice::Auto, Settings::default())
        .expect("built-in scene loads")
}

/// A built-in or generated scene after `steps` steps.
fn stepped(scene: &str, steps: usize) -> World {
    let mut world = load(scene);
    for _ in 0..steps {
        world.step();
    }
    world
}

fn renderer_or_skip(world: &World, width: u32, height: u32) -> Option<OffscreenRenderer> {
    match OffscreenRenderer::new(world, width, height) {
        Ok(r) => Some(r),
        // Only the want of an adapter skips; any other failure is the renderer's.
        Err(e) if e.downcast_ref::<tumble::viewer::gpu::NoGpu>().is_none() => panic!("{e}"),
        Err(e) if std::env::var("TUMBLE_REQUIRE_GPU").is_ok_and(|v| v == "1") => {
            panic!("TUMBLE_REQUIRE_GPU=1 but {e}")
        }
        Err(e) => {
            eprintln!("skipping: {e}");
            None
        }
    }
}

fn framed(world: &World, width: u32, height: u32) -> OrbitCamera {
    let mut camera = OrbitCamera::default();
    camera.frame(world, width as f64 / height as f64);
    camera
}

/// Every surface vertex of every body, as the compute pass running the vertex shader's
/// `body_point` computes it from the instance buffer, against the core's `currV`.
fn check_vertices(scene: &str, steps: usize) {
    let world = stepped(scene, steps);
    let Some(mut r) = renderer_or_skip(&world, 64, 64) else {
        return;
    };
    if !r.gpu.has_compute() {
        let why = format!("{} has no compute shaders", r.gpu.description());
        // CI's adapter (lavapipe) has them: a readback skipped there would pass untested.
        if std::env::var("TUMBLE_REQUIRE_GPU").is_ok_and(|v| v == "1") {
            panic!("TUMBLE_REQUIRE_GPU=1 but {why}");
        }
        eprintln!("skipping the vertex readback: {why}");
        return;
    }
    let camera = framed(&world, 64, 64);
    r.render(&world, &camera, &DrawOptions::default()).unwrap();
    let gpu_points = r.renderer.gpu_body_points(&r.gpu).unwrap();
    assert_eq!(gpu_points.len(), world.bodies.len());
    let mut compared = 0;
    let mut worst: f64 = 0.0;
    for (index, body) in world.bodies.iter().enumerate() {
        let core = world.current_vertices(index);
        let shape = &world.shapes[body.shape];
        let on_surface: std::collections::BTreeSet<u32> =
            shape.triangles.iter().flatten().copied().collect();
        for (v, expected) in core.iter().enumerate() {
            let got = gpu_points[index].get(v).copied().flatten();
            if !on_surface.contains(&(v as u32)) {
                continue;
            }
            let got = got.unwrap_or_else(|| {
                panic!("body {index} vertex {v}: on the surface but not computed")
            });
            let got = DVec3::new(got[0] as f64, got[1] as f64, got[2] as f64);
            // f32 rounding of the inputs (vertex, quaternion, centre of mass) and a few
            // operations: a few ulps of the magnitudes involved.
            let scale = body.position.length() + shape.rest_vertices[v].length() + 1.0;
            let error = (got - *expected).length();
            assert!(
                error <= 1e-6 * scale,
                "{scene}: body {index} vertex {v}: shader {got} vs core {expected} (error {error:e})"
            );
            worst = worst.max(error / scale);
            compared += 1;
        }
    }
    assert!(compared > 0);
    eprintln!("{scene}: {compared} vertices agree with the core, worst relative error {worst:e}");
}

#[test]
fn shader_vertices_equal_core_vertices_mixed() {
    check_vertices("mixed", 120);
}

#[test]
fn shader_vertices_equal_core_vertices_stress() {
    check_vertices("stress", 60);
}

#[test]
fn shader_vertices_equal_core_vertices_with_constraints() {
    check_vertices("two-chain", 80);
}

/// What the core's geometry says pixel (i, j) shows: the body hit by the rays through the
/// pixel's centre and its 8 neighbours' centres, `Some(None)` for background, `None` when they
/// disagree (an edge: anti-aliased, not checked).
fn expected_at(
    world: &World,
    camera: &OrbitCamera,
    i: u32,
    j: u32,
    width: u32,
    height: u32,
) -> Option<Option<usize>> {
    let mut seen: Option<Option<usize>> = None;
    for dj in -1i32..=1 {
        for di in -1i32..=1 {
            let (x, y) = (i as f64 + 0.5 + di as f64, j as f64 + 0.5 + dj as f64);
            let (origin, dir) = camera.ray(x, y, width as f64, height as f64);
            let hit = pick(world, (origin, dir), true).map(|(b, _)| b);
            match seen {
                None => seen = Some(hit),
                Some(s) if s != hit => return None,
                _ => {}
            }
        }
    }
    seen
}

fn close(a: [u8; 4], b: [u8; 3], tolerance: i32) -> bool {
    (0..3).all(|k| (a[k] as i32 - b[k] as i32).abs() <= tolerance)
}

fn body_bytes(world: &World, index: usize) -> [u8; 3] {
    palette::srgb_bytes(palette::body_srgb(index, world.bodies[index].fixed))
}

/// Flat-shaded: every body pixel is exactly the body's palette colour, so the picture can be
/// compared with the core pixel by pixel at the projected centres of the bodies.
fn check_pixels(scene: &str, steps: usize, width: u32, height: u32) {
    let world = stepped(scene, steps);
    let Some(mut r) = renderer_or_skip(&world, width, height) else {
        return;
    };
    let camera = framed(&world, width, height);
    let options = DrawOptions {
        grid: false,
        constraints: false,
        flat: true,
        ..DrawOptions::default()
    };
    let image: Image = r.render(&world, &camera, &options).unwrap();
    assert_eq!((image.width, image.height), (width, height));
    let background = palette::srgb_bytes(palette::BACKGROUND_SRGB);

    let mut bodies_checked = 0;
    let mut own_colour = 0;
    for (index, body) in world.bodies.iter().enumerate() {
        let Some((x, y)) = camera.project(body.position, width as f64, height as f64) else {
            continue;
        };
        if x < 2.0 || y < 2.0 || x >= width as f64 - 2.0 || y >= height as f64 - 2.0 {
            continue;
        }
        let (i, j) = (x as u32, y as u32);
        let Some(expected) = expected_at(&world, &camera, i, j, width, height) else {
            continue;
        };
        let pixel = image.pixel(i, j);
        match expected {
            Some(hit) => {
                assert!(
                    close(pixel, body_bytes(&world, hit), 2),
                    "{scene}: centre of body {index} at ({i}, {j}) should show body {hit} {:?}, got {pixel:?}",
                    body_bytes(&world, hit)
                );
                own_colour += (hit == index) as usize;
            }
            None => assert!(
                close(pixel, background, 1),
                "{scene}: ({i}, {j}) should be background, got {pixel:?}"
            ),
        }
        bodies_checked += 1;
    }
    assert!(
        own_colour >= world.bodies.len() / 2,
        "{scene}: only {own_colour} of {} bodies visible at their centres",
        world.bodies.len()
    );

    // Background and bodies on a coarse grid of pixels.
    let mut background_checked = 0;
    for j in (3..height - 3).step_by(9) {
        for i in (3..width - 3).step_by(9) {
            match expected_at(&world, &camera, i, j, width, height) {
                Some(None) => {
                    assert!(
                        close(image.pixel(i, j), background, 1),
                        "{scene}: ({i}, {j}) should be background, got {:?}",
                        image.pixel(i, j)
                    );
                    background_checked += 1;
                }
                Some(Some(hit)) => {
                    assert!(
                        close(image.pixel(i, j), body_bytes(&world, hit), 2),
                        "{scene}: ({i}, {j}) should show body {hit}, got {:?}",
                        image.pixel(i, j)
                    );
                }
                None => {}
            }
        }
    }
    assert!(background_checked > 20);
    eprintln!(
        "{scene}: {bodies_checked} body centres ({own_colour} showing their own body) and {background_checked} background pixels match the core"
    );
}

#[test]
fn pixels_match_core_geometry_mixed() {
    check_pixels("mixed", 60, 320, 200);
}

#[test]
fn pixels_match_core_geometry_stress() {
    check_pixels("stress", 40, 400, 300);
}

/// Lit: body pixels are not the background and are nearer (in chromaticity) to their own
/// body's colour than to any other body's; the ground grid shows under the bodies.
#[test]
fn lit_render_keeps_body_colours() {
    let world = stepped("mixed", 60);
    let (width, height) = (320, 200);
    let Some(mut r) = renderer_or_skip(&world, width, height) else {
        return;
    };
    let camera = framed(&world, width, height);
    let image = r.render(&world, &camera, &DrawOptions::default()).unwrap();
    let chroma = |c: [f64; 3]| {
        let s = c[0] + c[1] + c[2] + 1e-9;
        [c[0] / s, c[1] / s, c[2] / s]
    };
    let distance = |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>();
    let mut checked = 0;
    for (index, body) in world.bodies.iter().enumerate() {
        let Some((x, y)) = camera.project(body.position, width as f64, height as f64) else {
            continue;
        };
        let (i, j) = (x as u32, y as u32);
        if i < 2 || j < 2 || i >= width - 2 || j >= height - 2 {
            continue;
        }
        if expected_at(&world, &camera, i, j, width, height) != Some(Some(index)) {
            continue;
        }
        let p = image.pixel(i, j);
        let got = chroma([p[0] as f64, p[1] as f64, p[2] as f64]);
        let nearest = (0..world.bodies.len())
            .min_by(|&a, &b| {
                let ca = body_bytes(&world, a).map(|v| v as f64);
                let cb = body_bytes(&world, b).map(|v| v as f64);
                distance(got, chroma(ca)).total_cmp(&distance(got, chroma(cb)))
            })
            .unwrap();
        assert_eq!(
            nearest, index,
            "lit pixel {p:?} at the centre of body {index} looks like body {nearest}"
        );
        checked += 1;
    }
    assert!(checked >= 4, "only {checked} bodies checked");
    // The ground plane is visible below the scene's centre, and differs from the background.
    let ground = palette::srgb_bytes(palette::GROUND_SRGB);
    let ground_pixels = image
        .rgba
        .chunks_exact(4)
        .filter(|p| close([p[0], p[1], p[2], 255], ground, 2))
        .count();
    assert!(
        ground_pixels > (width * height / 20) as usize,
        "ground plane barely visible: {ground_pixels} pixels"
    );
}

#[test]
fn one_instanced_draw_per_shape() {
    let world = load("stress");
    let Some(r) = renderer_or_skip(&world, 32, 32) else {
        return;
    };
    let used: std::collections::BTreeSet<usize> = world.bodies.iter().map(|b| b.shape).collect();
    assert_eq!(r.renderer.body_draw_calls(), used.len());
    assert!(used.len() < world.bodies.len() / 4);
}

#[test]
fn instance_data_is_the_pose_in_f32() {
    let world = stepped("mixed", 30);
    let Some(mut r) = renderer_or_skip(&world, 32, 32) else {
        return;
    };
    let camera = framed(&world, 32, 32);
    r.render(
        &world,
        &camera,
        &DrawOptions {
            selected: Some(2),
            ..DrawOptions::default()
        },
    )
    .unwrap();
    for (index, body) in world.bodies.iter().enumerate() {
        let inst = r.renderer.instance_of(index).unwrap();
        assert_eq!(inst.rotation, body.orientation.as_quat().to_array());
        assert_eq!(&inst.com[..3], &body.position.as_vec3().to_array()[..]);
        assert_eq!(inst.color[3], if index == 2 { 1.0 } else { 0.0 });
    }
}

/// Where the ray from the camera through pixel centre `(x, y)` meets the ground (y = 0), when
/// no body is in the way.
fn ground_point(
    world: &World,
    camera: &OrbitCamera,
    x: f64,
    y: f64,
    size: (u32, u32),
) -> Option<DVec3> {
    let (origin, dir) = camera.ray(x, y, size.0 as f64, size.1 as f64);
    if dir.y >= -1e-9 || pick(world, (origin, dir), true).is_some() {
        return None;
    }
    Some(origin + dir * (-origin.y / dir.y))
}

/// Whether the key light is blocked at ground point `p`: a CPU ray cast towards the light
/// against the core's triangles.
fn in_shadow(world: &World, p: DVec3) -> bool {
    let light = tumble::viewer::shadow::light_direction();
    pick(world, (p + DVec3::Y * 1e-9, light), true).is_some()
}

fn brightness(p: [u8; 4]) -> i32 {
    p[0] as i32 + p[1] as i32 + p[2] as i32
}

/// Shadows: every ground pixel that a CPU ray cast towards the key light finds blocked is darker
/// than the same pixel rendered without shadows (and than open ground), and every one it finds
/// lit is unchanged. Pixels near a shadow's edge (filtered) or a body's outline are not judged.
#[test]
fn ground_in_the_shadow_of_a_body_is_darker_than_open_ground() {
    let world = stepped("mixed", 60);
    let size = (320, 240);
    let Some(mut r) = renderer_or_skip(&world, size.0, size.1) else {
        return;
    };
    let mut camera = OrbitCamera {
        pitch: 55f64.to_radians(),
        ..OrbitCamera::default()
    };
    camera.frame(&world, size.0 as f64 / size.1 as f64);
    let options = DrawOptions::default();
    let shadowed = r.render(&world, &camera, &options).unwrap();
    let plain = r
        .render(
            &world,
            &camera,
            &DrawOptions {
                shadows: false,
                ..options
            },
        )
        .unwrap();
    let ground = palette::srgb_bytes(palette::GROUND_SRGB);
    let open_ground = brightness([ground[0], ground[1], ground[2], 255]);
    // A shadow's filtered edge spans a few texels of a map covering the ground (a few times the
    // scene): judge points whose neighbours this far away agree.
    let boxes = world.body_aabbs();
    let lo = boxes.iter().fold(DVec3::INFINITY, |m, b| m.min(b.min));
    let hi = boxes.iter().fold(DVec3::NEG_INFINITY, |m, b| m.max(b.max));
    let margin = 0.02 * (hi - lo).length();
    let around: Vec<(f64, f64)> = (0..9)
        .map(|k| (2.0 * (k % 3) as f64 - 2.0, 2.0 * (k / 3) as f64 - 2.0))
        .collect();
    let compass: Vec<DVec3> = (0..8)
        .map(|k| {
            let a = k as f64 * std::f64::consts::FRAC_PI_4;
            DVec3::new(a.cos(), 0.0, a.sin())
        })
        .collect();
    let (mut dark, mut lit) = (0, 0);
    for j in (2..size.1 - 2).step_by(2) {
        for i in (2..size.0 - 2).step_by(2) {
            let (x, y) = (i as f64 + 0.5, j as f64 + 0.5);
            // The pixel and its neighbours 2 pixels away all see the ground.
            let points: Option<Vec<DVec3>> = around
                .iter()
                .map(|(dx, dy)| ground_point(&world, &camera, x + dx, y + dy, size))
                .collect();
            let Some(points) = points else { continue };
            let p = points[4];
            let blocked = in_shadow(&world, p);
            let steady = compass
                .iter()
                .all(|&d| in_shadow(&world, p + margin * d) == blocked);
            if !steady {
                continue;
            }
            let (with, without) = (shadowed.pixel(i, j), plain.pixel(i, j));
            if blocked {
                assert!(
                    brightness(with) * 10 < brightness(without) * 8,
                    "({i}, {j}) at {p} is in shadow but {with:?} is not darker than {without:?}"
                );
                if close(without, ground, 1) {
                    assert!(brightness(with) < open_ground - 10);
                }
                dark += 1;
            } else {
                assert!(
                    close(with, [without[0], without[1], without[2]], 2),
                    "({i}, {j}) at {p} is lit but {with:?} differs from {without:?}"
                );
                lit += 1;
            }
        }
    }
    eprintln!("shadows: {dark} shadowed and {lit} lit ground pixels agree with the ray casts");
    assert!(
        dark >= 20 && lit >= 200,
        "{dark} shadowed, {lit} lit pixels judged"
    );
}

/// Side by side: each pane shows its own world, as the core's geometry says, through the same
/// camera at the pane's aspect.
#[test]
fn compared_worlds_are_drawn_side_by_side() {
    let mut a = load("mixed");
    let mut b =
        tumble::scene::load("mixed", &ConstraintsChoice::Auto, Settings::accurate()).unwrap();
    for _ in 0..80 {
        a.step();
        b.step();
    }
    let (width, height) = (480, 200);
    let Some(mut r) = renderer_or_skip(&a, width, height) else {
        return;
    };
    let pane = (width / 2, height);
    let mut camera = OrbitCamera::default();
    camera.frame(&a, pane.0 as f64 / pane.1 as f64);
    let options = DrawOptions {
        grid: false,
        constraints: false,
        flat: true,
        ..DrawOptions::default()
    };
    let image = r.render_worlds(&[&a, &b], &camera, &options, &[]).unwrap();
    let mut differ = 0;
    for (k, world) in [&a, &b].into_iter().enumerate() {
        let mut checked = 0;
        for index in 0..world.bodies.len() {
            let Some((x, y)) =
                camera.project(world.bodies[index].position, pane.0 as f64, pane.1 as f64)
            else {
                continue;
            };
            let (i, j) = (x as u32, y as u32);
            if i < 2 || j < 2 || i >= pane.0 - 2 || j >= pane.1 - 2 {
                continue;
            }
            let Some(Some(hit)) = expected_at(world, &camera, i, j, pane.0, pane.1) else {
                continue;
            };
            let pixel = image.pixel(i + k as u32 * pane.0, j);
            assert!(
                close(pixel, body_bytes(world, hit), 2),
                "pane {k}: ({i}, {j}) should show body {hit}, got {pixel:?}"
            );
            checked += 1;
            differ +=
                ((a.bodies[index].position - b.bodies[index].position).length() > 0.1) as usize;
        }
        assert!(
            checked >= world.bodies.len() / 2,
            "pane {k}: {checked} bodies checked"
        );
    }
    assert!(differ > 0, "the two worlds should differ somewhere");
}

/// Resting bodies of the soft step fall asleep; the viewer draws them dimmed (same hue, darker)
/// and the others in their own colour.
#[test]
fn asleep_bodies_are_dimmed() {
    let settings = Settings {
        restitution: 0.2,
        ..Settings::accurate()
    };
    let mut world = tumble::scene::load("mixed", &ConstraintsChoice::Auto, settings).unwrap();
    let mut steps = 0;
    while world.bodies.iter().all(|b| !b.asleep) && steps < 2000 {
        world.step();
        steps += 1;
    }
    assert!(
        world.bodies.iter().any(|b| b.asleep),
        "nothing asleep after {steps} steps"
    );
    let Some(mut r) = renderer_or_skip(&world, 32, 32) else {
        return;
    };
    let camera = framed(&world, 32, 32);
    r.render(&world, &camera, &DrawOptions::default()).unwrap();
    for (index, body) in world.bodies.iter().enumerate() {
        let own = palette::linear(palette::body_srgb(index, body.fixed));
        let expected = if body.asleep {
            palette::asleep(own)
        } else {
            own
        };
        let inst = r.renderer.instance_of(index).unwrap();
        assert_eq!(&inst.color[..3], &expected[..], "body {index}");
        if body.asleep {
            let sum = |c: [f32; 3]| c.iter().sum::<f32>();
            assert!(sum(expected) < 0.5 * sum(own), "body {index} not dimmed");
        }
    }
}

/// With fixed bodies hidden, a pile's bin shows what is inside it: from the framed view the
/// walls cover the pile, hidden they leave no pixel of their colour and the bodies appear.
#[test]
fn hidden_fixed_bodies_leave_no_pixel_and_show_the_pile() {
    let world = stepped("pile-60", 100);
    let (width, height) = (96, 72);
    let Some(mut r) = renderer_or_skip(&world, width, height) else {
        return;
    };
    let camera = framed(&world, width, height);
    let fixed: Vec<[u8; 3]> = (world.bodies.iter().enumerate())
        .filter(|(_, b)| b.fixed)
        .map(|(i, _)| body_bytes(&world, i))
        .collect();
    let moving: Vec<[u8; 3]> = (world.bodies.iter().enumerate())
        .filter(|(_, b)| !b.fixed)
        .map(|(i, _)| body_bytes(&world, i))
        .collect();
    assert!(!fixed.is_empty() && fixed.iter().all(|f| !moving.contains(f)));
    let mut counts = |fixed_bodies: bool| {
        let options = DrawOptions {
            grid: false,
            flat: true,
            fixed_bodies,
            ..DrawOptions::default()
        };
        let image = r.render(&world, &camera, &options).unwrap();
        let pixels = (0..height).flat_map(|j| (0..width).map(move |i| (i, j)));
        let mut n = (0, 0);
        for p in pixels.map(|(i, j)| image.pixel(i, j)) {
            n.0 += fixed.iter().any(|&c| close(p, c, 2)) as usize;
            n.1 += moving.iter().any(|&c| close(p, c, 2)) as usize;
        }
        n
    };
    let (shown, hidden) = (counts(true), counts(false));
    assert!(shown.0 > 500, "walls shown: {shown:?}");
    assert_eq!(hidden.0, 0, "walls hidden: {hidden:?}");
    assert!(
        hidden.1 > shown.1 + 100,
        "shown {shown:?}, hidden {hidden:?}"
    );
}

/// A recording stopped before its first frame leaves no video: a GIF of no frame would be a
/// file with no picture. (Skipped, as the rendering tests are, without a GPU adapter.)
#[test]
fn a_recording_stopped_before_its_first_frame_leaves_no_file() {
    let world = load("mixed");
    if renderer_or_skip(&world, 64, 48).is_none() {
        return;
    }
    let dir = std::env::temp_dir().join(format!("tumble-no-frame-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let options = tumble::viewer::RecordOptions {
        output: dir.join("none.gif"),
        seconds: 1.0,
        fps: 10.0,
        width: 64,
        height: 48,
        camera: None,
        draw: DrawOptions::default(),
        compare: None,
    };
    let report = tumble::viewer::record(world, &options, &mut |_, _| {}, &|| true).unwrap();
    let left: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().collect();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(report.interrupted && report.frames == 0);
    assert!(left.is_empty(), "{left:?}");
}
