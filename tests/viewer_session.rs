//! The viewer's session, driven headless through the API the window uses: rewinding repeats the
//! steps bit for bit (both solvers, one world or two compared), compared worlds step with their
//! own settings, a grab pulls with the force of a critically damped spring, and the scene reloads
//! when its files change (an error keeps the old scene).
#![cfg(feature = "viewer")]

use glam::{DQuat, DVec3};
use std::path::{Path, PathBuf};
use tumble::scene::assets;
use tumble::viewer::{SceneSource, Session, grab};
use tumble::{ConstraintsChoice, RigidBody, Settings, Shape, World};

fn load(scene: &str, settings: Settings) -> World {
    tumble::scene::load(scene, &ConstraintsChoice::Auto, settings).unwrap()
}

fn session(scene: &str, settings: Settings) -> Session {
    Session::new(load(scene, settings), SceneSource::named(scene))
}

/// Every body's pose and velocities as bits, and the time.
fn bits(world: &World) -> Vec<u64> {
    let mut out = vec![world.time.to_bits(), world.step_count];
    for b in &world.bodies {
        let (p, q, v, w) = (
            b.position,
            b.orientation,
            b.linear_velocity,
            b.angular_velocity,
        );
        let values = [
            p.x, p.y, p.z, q.x, q.y, q.z, q.w, v.x, v.y, v.z, w.x, w.y, w.z,
        ];
        out.extend(values.iter().map(|x| x.to_bits()));
    }
    out
}

fn all_bits(session: &Session) -> Vec<Vec<u64>> {
    session.lanes.iter().map(|l| bits(&l.world)).collect()
}

/// 200 steps, back to step 100, 100 steps: the same bits as the first run's step 200.
fn check_rewind(session: &mut Session, what: &str) {
    for _ in 0..200 {
        session.step_once();
    }
    let first = all_bits(session);
    assert!(session.seek_step(100), "{what}: step 100 is in the history");
    assert_eq!(session.world().step_count, 100, "{what}");
    assert!(!session.playing, "{what}: seeking pauses");
    for _ in 0..100 {
        session.step_once();
    }
    assert!(first == all_bits(session), "{what}: rewound run differs");
    assert!(
        session.timeline.at_end(),
        "{what}: the old future was dropped"
    );
    assert_eq!(session.timeline.len(), 201, "{what}");
}

#[test]
fn rewinding_repeats_the_steps_bit_for_bit() {
    for settings in [Settings::default(), Settings::accurate()] {
        for scene in ["pile-60", "two-chain"] {
            let what = format!("{scene}, solver {:?}", settings.solver);
            check_rewind(&mut session(scene, settings.clone()), &what);
        }
    }
}

#[test]
fn compared_worlds_rewind_in_lockstep() {
    let mut s = session("stress", Settings::default());
    s.compare(Settings::accurate());
    check_rewind(&mut s, "stress, coursework against accurate");
    assert_eq!(s.lanes[1].world.step_count, 200);
}

#[test]
fn the_history_is_bounded_by_its_memory_budget() {
    let mut s = session("pile-60", Settings::default());
    s.step_once();
    let per_step = s.timeline.span().bytes / 2;
    s.timeline.set_budget(50 * per_step);
    for _ in 0..200 {
        s.step_once();
    }
    let span = s.timeline.span();
    assert!(span.bytes <= 50 * per_step, "{span:?}");
    assert!(
        (45..=50).contains(&s.timeline.len()),
        "{}",
        s.timeline.len()
    );
    assert_eq!(span.last_step, 201);
    assert!(!s.seek_step(100), "step 100 fell out of the history");
    assert!(s.seek_step(span.first_step));
    assert_eq!(s.world().step_count, span.first_step);
}

/// Lowering the budget while rewound keeps the state the worlds are at, and the history in
/// order: resuming from it goes on from that state.
#[test]
fn a_smaller_budget_while_rewound_keeps_the_current_state() {
    let mut s = session("pile-60", Settings::default());
    for _ in 0..100 {
        s.step_once();
    }
    assert!(s.seek_step(20));
    let at = all_bits(&s);
    let per_step = s.timeline.span().bytes / s.timeline.len();
    s.timeline.set_budget(30 * per_step);
    assert!(s.timeline.len() <= 30, "{}", s.timeline.len());
    assert_eq!(s.timeline.step_at(s.timeline.cursor()), Some(20));
    let span = s.timeline.span();
    assert!(span.first_step <= 20 && 20 <= span.last_step, "{span:?}");
    s.step_forward();
    s.step_back();
    assert!(all_bits(&s) == at, "back at step 20");
    for _ in 0..3 {
        s.step_once();
    }
    assert_eq!(s.world().step_count, 23);
    assert_eq!(s.timeline.span().last_step, 23);
    let steps: Vec<u64> = (0..s.timeline.len())
        .map(|k| s.timeline.step_at(k).unwrap())
        .collect();
    assert!(steps.windows(2).all(|w| w[1] == w[0] + 1), "{steps:?}");
}

/// A compared world whose steps leave its time where it was (a time step of 1e-300) or that
/// would need millions of them to keep up returns each frame after at most 10,000 steps: it
/// stepped for ever in one frame, the window frozen past Ctrl-C.
#[test]
fn a_compared_world_that_cannot_keep_up_steps_a_bounded_amount_each_frame() {
    for dt in [1e-300, 1e-9] {
        let mut s = session("cube", Settings::default());
        s.compare(Settings {
            time_step: dt,
            ..Settings::default()
        });
        s.advance(0.05, |_| {});
        let (a, b) = (&s.lanes[0].world, &s.lanes[1].world);
        assert!(a.step_count >= 1, "dt {dt}: the first world stepped");
        assert!(
            b.step_count <= 10_000 * a.step_count,
            "dt {dt}: {}",
            b.step_count
        );
    }
}

/// Two lanes of a comparison each equal an independent world stepped with their settings, the
/// second at half the time step (twice the steps).
#[test]
fn compared_worlds_step_with_their_own_settings() {
    let mut s = session("tower", Settings::default());
    let fine = Settings {
        time_step: 0.01,
        ..Settings::accurate()
    };
    s.compare(fine.clone());
    for _ in 0..10 {
        s.advance(0.05, |_| {});
    }
    let (a, b) = (&s.lanes[0].world, &s.lanes[1].world);
    assert_eq!((a.step_count, b.step_count), (25, 50));
    assert!((a.time - b.time).abs() < 1e-9);
    let mut alone_a = load("tower", Settings::default());
    let mut alone_b = load("tower", fine);
    for _ in 0..25 {
        alone_a.step();
    }
    for _ in 0..50 {
        alone_b.step();
    }
    assert!(
        bits(a) == bits(&alone_a),
        "world A differs from the world alone"
    );
    assert!(
        bits(b) == bits(&alone_b),
        "world B differs from the world alone"
    );
    assert!(
        bits(a)[2..] != bits(b)[2..],
        "the settings make a difference"
    );
}

/// Boxes of 2 x 1 x 1.5 at `(density, position, orientation)`, in a session named `name`.
fn boxes(settings: Settings, placed: &[(f64, DVec3, DQuat)], name: &str) -> Session {
    let shape = Shape::from_tet_mesh(&assets::cuboid(DVec3::new(1.0, 0.5, 0.75))).unwrap();
    let bodies = placed
        .iter()
        .map(|&(density, position, orientation)| {
            RigidBody::on_shape(&shape, 0, density, false, position, orientation)
        })
        .collect();
    let world = World::new(
        vec![shape],
        vec!["box".into()],
        bodies,
        Vec::new(),
        settings,
    );
    Session::new(world, SceneSource::named(name))
}

/// Two boxes far apart in the air, of densities 60x apart.
fn two_boxes(settings: Settings) -> Session {
    let tilt = DQuat::from_rotation_z(0.3);
    let placed = [
        (50.0, DVec3::new(-20.0, 40.0, 0.0), tilt),
        (3000.0, DVec3::new(20.0, 40.0, 0.0), tilt),
    ];
    boxes(settings, &placed, "two boxes")
}

/// The closed form of a critically damped spring-damper of frequency `hertz` on mass `m`,
/// integrated implicitly over `h`: the force from offset `c` and velocity `v`.
fn spring_force(m: f64, hertz: f64, h: f64, c: DVec3, v: DVec3) -> DVec3 {
    let omega = std::f64::consts::TAU * hertz;
    let (k, d) = (m * omega * omega, 2.0 * m * omega);
    -(k * c + (h * k + d) * v) / (1.0 + (h * h * k + h * d) / m)
}

/// Asserts that `force` is [`spring_force`] at 3 Hz on the grabbed `body` pulled to `target` over
/// a substep `h`; returns that force.
fn assert_grab_spring(
    force: DVec3,
    (body, target): (&RigidBody, DVec3),
    h: f64,
    what: &str,
) -> DVec3 {
    let expected = spring_force(
        body.mass,
        3.0,
        h,
        body.position - target,
        body.linear_velocity,
    );
    assert!(
        (force - expected).length() <= 1e-9 * expected.length(),
        "{what}: force {force} vs the spring's {expected} over h = {h}"
    );
    expected
}

#[test]
fn a_grab_pulls_with_the_force_of_a_critically_damped_spring() {
    for settings in [Settings::default(), Settings::accurate()] {
        let what = format!("solver {:?}", settings.solver);
        let mut s = two_boxes(settings.clone());
        s.grab_hertz = 3.0;
        for _ in 0..10 {
            s.step_once();
        }
        let body = s.world().bodies[0].clone();
        let target = body.position + DVec3::new(2.0, 3.0, -1.0);
        // Grabbed where it is, as the window grabs, then dragged.
        assert!(s.grab(0, DVec3::ZERO, body.position), "{what}");
        s.drag_grab(target);
        // In free fall every step takes the setting's substeps.
        assert_eq!(s.lanes[0].last.substeps, settings.substeps, "{what}");
        let (point, force) = grab::force(s.world(), s.lanes[0].last.substeps).unwrap();
        assert_eq!(point, body.position);
        let h = settings.time_step / settings.substeps as f64;
        assert_grab_spring(force, (&body, target), h, &what);
        // Pulled to the target within 2 s (from 3.7 units away), hanging under it: gravity
        // stretches the spring by g / omega^2, and by up to twice that with the step's damping.
        for _ in 0..100 {
            s.step_once();
        }
        let sag = 9.8 / (std::f64::consts::TAU * 3.0).powi(2);
        let offset = s.world().bodies[0].position - target;
        assert!(
            offset.y < 0.0 && offset.y > -2.5 * sag && offset.x.abs() + offset.z.abs() < 1e-6,
            "{what}: {offset} from the target"
        );
    }
}

/// A box resting on the ground at dt 0.04: the soft step's steps that begin touching take eight
/// substeps, not the setting's four, and the grab's displayed force is the spring's over the
/// substep the solver takes (a fixed four would show a force 1 / (1 + h^2 k / m + h d / m)
/// apart).
#[test]
fn the_grab_force_shown_is_over_the_substep_the_soft_step_takes() {
    let settings = Settings {
        time_step: 0.04,
        ..Settings::accurate()
    };
    let on_ground = [(50.0, DVec3::new(0.0, 0.5, 0.0), DQuat::IDENTITY)];
    let mut s = boxes(settings.clone(), &on_ground, "a box on the ground");
    s.grab_hertz = 3.0;
    for _ in 0..5 {
        s.step_once();
    }
    let substeps = s.lanes[0].last.substeps;
    assert_eq!(substeps, 8, "a touching step at dt 0.04");
    let body = s.world().bodies[0].clone();
    let target = body.position + DVec3::new(0.0, 3.0, 0.0);
    assert!(s.grab(0, DVec3::ZERO, body.position));
    s.drag_grab(target);
    let (_, force) = grab::force(s.world(), substeps).unwrap();
    let expected = assert_grab_spring(force, (&body, target), settings.time_step / 8.0, "");
    let (_, four) = grab::force(s.world(), 0).unwrap();
    assert!(
        (four - expected).length() > 1e-6 * expected.length(),
        "the setting's substeps give another force"
    );
}

/// The grabbed point moves the same way on a light and a heavy body: the force scales with the
/// mass.
#[test]
fn light_and_heavy_bodies_follow_alike() {
    let local = DVec3::new(0.0, 0.5, 0.0);
    let offset = DVec3::new(3.0, 2.0, 1.0);
    let moved: Vec<DVec3> = (0..2)
        .map(|i| {
            let mut s = two_boxes(Settings::default());
            let start = s.world().bodies[i].world_point(local);
            assert!(s.grab(i, local, start));
            s.drag_grab(start + offset);
            for _ in 0..60 {
                s.step_once();
            }
            s.world().bodies[i].world_point(local) - start
        })
        .collect();
    let masses: Vec<f64> = two_boxes(Settings::default())
        .world()
        .bodies
        .iter()
        .map(|b| b.mass)
        .collect();
    assert!(masses[1] > 50.0 * masses[0]);
    assert!((moved[0] - offset).length() < 0.3, "moved {}", moved[0]);
    assert!(
        (moved[0] - moved[1]).length() < 1e-6,
        "the light body's point moved {}, the heavy one's {}",
        moved[0],
        moved[1]
    );
}

/// A paused drag moves the grabbed body of every world by the cursor's displacement, each from
/// where it was (compared worlds drift apart: here the second falls at a tenth of the time
/// step); a click alone moves nothing.
#[test]
fn a_paused_drag_moves_the_pose_in_every_world() {
    let mut s = two_boxes(Settings::default());
    s.compare(Settings {
        time_step: 0.002,
        ..Settings::accurate()
    });
    for _ in 0..5 {
        s.step_once();
    }
    s.pause();
    let local = DVec3::new(0.5, 0.0, 0.25);
    let before: Vec<RigidBody> = s.lanes.iter().map(|l| l.world.bodies[1].clone()).collect();
    let apart = before[1].world_point(local) - before[0].world_point(local);
    assert!(
        apart.length() > 1e-3,
        "the worlds' bodies are apart: {apart}"
    );
    let picked = before[0].world_point(local);
    assert!(s.grab(1, local, picked));
    for (lane, b) in s.lanes.iter().zip(&before) {
        assert_eq!(&lane.world.bodies[1], b, "a click moves no body");
    }
    let moved = DVec3::new(-1.0, 2.0, 0.5);
    s.drag_grab(picked + moved);
    for (lane, b0) in s.lanes.iter().zip(&before) {
        let b = &lane.world.bodies[1];
        assert!((b.world_point(local) - (b0.world_point(local) + moved)).length() < 1e-12);
        assert_eq!(b.orientation, b0.orientation);
    }
    assert_eq!(
        s.world().bodies[1].linear_velocity,
        before[0].linear_velocity
    );
    s.release_grab();
    assert!(!s.grabbing());
    // The edited state is the history's current one: stepping back and forth comes back to it.
    s.step_back();
    s.step_forward();
    let target = picked + moved;
    assert!((s.world().bodies[1].world_point(local) - target).length() < 1e-12);
}

/// A sleeping stack's bottom box dragged out while paused and let go: the boxes it held up wake
/// and fall when play resumes (they were left asleep in the air), and a box held still by a
/// grab stays awake (it slept at 0.5 s and was woken by the next step, again and again).
#[test]
fn a_moved_or_held_body_keeps_its_island_awake() {
    let mut s = session("stack-3", Settings::accurate());
    for _ in 0..200 {
        s.step_once();
    }
    assert!(
        s.world().bodies.iter().all(|b| b.asleep),
        "the stack sleeps by 4 s"
    );
    s.pause();
    let local = DVec3::ZERO;
    let picked = s.world().bodies[0].position;
    assert!(s.grab(0, local, picked));
    s.drag_grab(picked + DVec3::new(5.0, 0.0, 0.0));
    s.release_grab();
    assert!(
        s.world().bodies.iter().all(|b| !b.asleep),
        "the island woke"
    );
    let top = s.world().bodies[2].position.y;
    for _ in 0..25 {
        s.step_once();
    }
    assert!(
        s.world().bodies[2].position.y < top - 0.3,
        "the top box falls: {} from {top}",
        s.world().bodies[2].position.y
    );
    // Held still where it rests, for 3 s.
    let mut s = session("stack-1", Settings::accurate());
    let picked = s.world().bodies[0].position;
    assert!(s.grab(0, local, picked));
    for _ in 0..150 {
        s.step_once();
        assert!(
            !s.world().bodies[0].asleep,
            "asleep at {} s",
            s.world().time
        );
    }
    s.release_grab();
    for _ in 0..100 {
        s.step_once();
    }
    assert!(s.world().bodies[0].asleep, "let go, it sleeps again");
}

/// A click on a body while rewound, without a drag, keeps the history after it.
#[test]
fn a_click_while_rewound_keeps_the_future() {
    let mut s = two_boxes(Settings::default());
    for _ in 0..10 {
        s.step_once();
    }
    assert!(s.seek_step(4));
    let local = DVec3::new(0.5, 0.0, 0.25);
    let picked = s.world().bodies[1].world_point(local);
    assert!(s.grab(1, local, picked));
    s.release_grab();
    assert_eq!(s.timeline.len(), 11);
    assert_eq!(s.timeline.span().last_step, 10);
}

/// A scratch directory with tumble's box mesh in it.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("tumble-viewer-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let mesh = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/box.mesh");
    std::fs::copy(mesh, dir.join("box.mesh")).unwrap();
    dir
}

fn boxes_scene(count: usize) -> String {
    let mut text = format!("{count}\n");
    for k in 0..count {
        text += &format!("box.mesh 1000 0  {} 5 0  1 0 0 0\n", 3 * k);
    }
    text
}

/// A scene written on Windows (a backslash in its mesh path, a Latin-1 accent in a comment)
/// loads, and the mesh it loads is the one watched for changes.
#[test]
fn a_scene_written_on_windows_watches_the_mesh_it_loads() {
    let dir = scratch("windows");
    std::fs::create_dir_all(dir.join("meshes")).unwrap();
    std::fs::rename(dir.join("box.mesh"), dir.join("meshes/box.mesh")).unwrap();
    let path = dir.join("w-scene.txt");
    let text = boxes_scene(1).replace("box.mesh", "meshes\\box.mesh");
    std::fs::write(
        &path,
        [b"# caf\xe9\r\n".as_slice(), text.as_bytes()].concat(),
    )
    .unwrap();
    let source = SceneSource::named(&path.to_string_lossy());
    let s = Session::new(source.load(Settings::default()).unwrap(), source);
    let watched: Vec<PathBuf> = s.watched_files().map(Path::to_path_buf).collect();
    let mesh = dir.join("meshes/box.mesh");
    assert!(
        watched
            .iter()
            .any(|w| w.canonicalize().ok() == mesh.canonicalize().ok())
    );
}

#[test]
fn an_edited_scene_file_reloads_and_an_error_keeps_the_old_scene() {
    let dir = scratch("reload");
    let path = dir.join("boxes-scene.txt");
    std::fs::write(&path, boxes_scene(1)).unwrap();
    let source = SceneSource::named(&path.to_string_lossy());
    let mut s = Session::new(source.load(Settings::default()).unwrap(), source);
    let watched: Vec<PathBuf> = s.watched_files().map(Path::to_path_buf).collect();
    assert!(watched.contains(&path) && watched.contains(&dir.join("box.mesh")));
    assert!(watched.contains(&dir.join("boxes-constraints.txt")));
    s.world_mut().settings.time_step = 0.01;
    s.step_once();
    assert!(s.poll_files().is_none(), "nothing changed");

    std::fs::write(&path, boxes_scene(2)).unwrap();
    assert!(matches!(s.poll_files(), Some(Ok(()))));
    assert_eq!(s.world().bodies.len(), 2);
    assert_eq!(s.world().step_count, 0);
    assert_eq!(s.world().settings.time_step, 0.01, "settings are kept");

    let broken = boxes_scene(2).replace("box.mesh 1000 0  3", "box.mesh 1000 0  x3");
    std::fs::write(&path, broken).unwrap();
    let error = s.poll_files().unwrap().unwrap_err();
    assert_eq!(
        (error.file.as_path(), error.line),
        (path.as_path(), Some(3))
    );
    assert_eq!(s.world().bodies.len(), 2, "the old scene stays");

    // Deleted, the scene file is an error and stays watched: written back, it reloads.
    std::fs::remove_file(&path).unwrap();
    assert!(matches!(s.poll_files(), Some(Err(_))));
    assert!(s.watched_files().any(|f| f == path), "still watched");
    std::fs::write(&path, boxes_scene(3)).unwrap();
    assert!(matches!(s.poll_files(), Some(Ok(()))));
    assert_eq!(s.world().bodies.len(), 3);
    // Editing the mesh reloads too.
    let mut mesh = std::fs::read_to_string(dir.join("box.mesh")).unwrap();
    mesh.push('\n');
    std::fs::write(dir.join("box.mesh"), mesh).unwrap();
    assert!(matches!(s.poll_files(), Some(Ok(()))));
    s.auto_reload = false;
    std::fs::write(&path, boxes_scene(1)).unwrap();
    assert!(s.poll_files().is_none(), "reloading is off");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_dropped_mesh_is_a_body_above_the_ground() {
    let dir = scratch("drop");
    let source = SceneSource::dropped(&dir.join("box.mesh"));
    assert_eq!(source, SceneSource::Mesh(dir.join("box.mesh")));
    let world = source.load(Settings::default()).unwrap();
    assert_eq!(world.bodies.len(), 1);
    let lowest = world
        .current_vertices(0)
        .iter()
        .map(|v| v.y)
        .fold(f64::INFINITY, f64::min);
    assert!(lowest > 0.0, "lowest point at {lowest}");
    let scene = dir.join("x-scene.txt");
    assert!(matches!(
        SceneSource::dropped(&scene),
        SceneSource::Scene { .. }
    ));
    let bad = dir.join("bad.off");
    std::fs::write(&bad, "OFF\n3 1 0\n0 0 0\n").unwrap();
    let error = SceneSource::dropped(&bad)
        .load(Settings::default())
        .unwrap_err();
    assert_eq!(error.file, bad);
    // Two tetrahedra apart: not convex, loaded with the warning a scene of it gets.
    let pair = dir.join("pair.off");
    let faces = "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n3 4 6 5\n3 4 5 7\n3 4 7 6\n3 5 6 7\n";
    let corners = "0 0 0\n1 0 0\n0 1 0\n0 0 1\n5 5 5\n6 5 5\n5 6 5\n5 5 6\n";
    std::fs::write(&pair, format!("OFF\n8 8 0\n{corners}{faces}")).unwrap();
    let world = SceneSource::dropped(&pair)
        .load(Settings::default())
        .unwrap();
    assert!(
        world.warnings.len() == 1 && world.warnings[0].contains("not convex"),
        "{:?}",
        world.warnings
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Every text the panel lays out in one headless frame.
fn panel_texts(session: &mut Session) -> Vec<String> {
    let state = &mut tumble::viewer::panel::PanelState::default();
    panel_frame(session, state, None).0
}

/// Every text a headless frame of the UI lays out, and the rectangle it leaves the view
/// (points, in a 1280 x 2000 window): the second frame, as egui sizes a new area in its first
/// without painting it.
fn panel_frame(
    session: &mut Session,
    state: &mut tumble::viewer::panel::PanelState,
    recording: Option<(&str, u64)>,
) -> (Vec<String>, egui::Rect) {
    let (shapes, view) = ui_frame(session, state, recording, egui::vec2(1280.0, 2000.0));
    let texts = (shapes.iter())
        .filter_map(|clipped| match &clipped.shape {
            egui::Shape::Text(text) => Some(text.galley.job.text.clone()),
            _ => None,
        })
        .collect();
    (texts, view)
}

/// The shapes of a headless frame of the UI in a window of `size` points, and the rectangle it
/// leaves the view: the second frame (see [`panel_frame`]).
fn ui_frame(
    session: &mut Session,
    state: &mut tumble::viewer::panel::PanelState,
    recording: Option<(&str, u64)>,
    size: egui::Vec2,
) -> (Vec<egui::epaint::ClippedShape>, egui::Rect) {
    use tumble::viewer::panel::{self, FrameInfo};
    let ctx = egui::Context::default();
    let input = egui::RawInput {
        screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, size)),
        ..Default::default()
    };
    let info = FrameInfo {
        frame_interval: 1.0 / 60.0,
        frame_work: 0.005,
        adapter: "none",
        msaa: 1,
        draw_calls: 0,
        recording,
    };
    panel::run(&ctx, input.clone(), session, state, &info);
    let frame = panel::run(&ctx, input, session, state, &info);
    (frame.output.shapes, frame.view)
}

/// In a small window the compared worlds' labels and the status lines over the view end within
/// their panes, side by side or as a ghost overlay, the panel shown or hidden (they ran under
/// the panel and into the other pane, up to stop 67).
#[test]
fn labels_stay_in_their_panes_in_a_small_window() {
    use tumble::viewer::compare::Layout;
    let mut s = session("tower", Settings::default());
    s.compare(Settings::accurate());
    s.step_once();
    // (A 400-point window with the panel shown leaves the view 40 points: room for no text.)
    for (size, layout, hidden) in [
        ((400.0, 300.0), Layout::SideBySide, true),
        ((800.0, 500.0), Layout::SideBySide, false),
        ((800.0, 500.0), Layout::SideBySide, true),
        ((640.0, 480.0), Layout::Ghost, false),
    ] {
        let mut state = tumble::viewer::panel::PanelState {
            hidden,
            ..Default::default()
        };
        state.draw.layout = layout;
        let size = egui::vec2(size.0, size.1);
        let (shapes, view) = ui_frame(&mut s, &mut state, None, size);
        let rect = [view.min.x, view.min.y, view.width(), view.height()];
        let panes = tumble::viewer::compare::panes(rect, 2, layout);
        let texts = shapes.iter().filter_map(|clipped| match &clipped.shape {
            egui::Shape::Text(text) => Some(text),
            _ => None,
        });
        let mut in_view = 0;
        for text in texts.filter(|t| view.contains(t.pos)) {
            in_view += 1;
            let right = text.pos.x + text.galley.rect.width();
            let pane = panes
                .iter()
                .find(|p| text.pos.x >= p.rect[0] && text.pos.x < p.rect[0] + p.rect[2]);
            let pane =
                pane.unwrap_or_else(|| panic!("{size:?}: {:?} in no pane", text.galley.job.text));
            assert!(
                right <= pane.rect[0] + pane.rect[2] + 0.5,
                "{size:?} {layout:?}: {:?} ends at {right}, its pane at {}",
                text.galley.job.text,
                pane.rect[0] + pane.rect[2]
            );
        }
        assert!(in_view >= 4, "{size:?}: {in_view} texts over the view");
    }
}

/// With the panel hidden (H) the view takes the whole window, and its corner says what the
/// panel would of a recording, the last message and how to show the panel again.
#[test]
fn a_hidden_panel_leaves_the_whole_window_to_the_view() {
    let mut s = session("two-chain", Settings::default());
    let mut state = tumble::viewer::panel::PanelState::default();
    let (shown, view) = panel_frame(&mut s, &mut state, Some(("out.gif", 1)));
    assert!(shown.iter().any(|t| t.contains("time step")), "{shown:?}");
    assert!(view.width() < 1000.0, "{view:?}");
    state.hidden = true;
    state.message = Some("screenshot written".into());
    let (texts, view) = panel_frame(&mut s, &mut state, Some(("out.gif", 1)));
    assert!(!texts.iter().any(|t| t.contains("time step")), "{texts:?}");
    assert_eq!(view.width(), 1280.0);
    for said in [
        "REC out.gif: 1 frame",
        "screenshot written",
        "H: show the panel",
    ] {
        assert!(texts.iter().any(|t| t == said), "{said}: {texts:?}");
    }
}

/// Settings from the command line beyond the panel's slider ranges stay as given until a slider
/// is dragged (the first frame clamped them, unsaid).
#[test]
fn the_panel_keeps_settings_beyond_its_sliders() {
    let given = Settings {
        time_step: 0.08,
        friction: 2.0,
        max_iterations: 1_000_000,
        tolerance: 0.0,
        substeps: 64,
        restitution_threshold: 10.0,
        full_substeps_from: 0.1,
        ..Settings::accurate()
    };
    let mut s = session("two-chain", given.clone());
    let texts = panel_texts(&mut s);
    assert!(texts.iter().any(|t| t.contains("time step")), "{texts:?}");
    let kept = &s.world().settings;
    assert_eq!(
        (kept.time_step, kept.friction, kept.max_iterations),
        (given.time_step, given.friction, given.max_iterations)
    );
    assert_eq!(
        (kept.tolerance, kept.substeps),
        (given.tolerance, given.substeps)
    );
    assert_eq!(
        (kept.restitution_threshold, kept.full_substeps_from),
        (given.restitution_threshold, given.full_substeps_from)
    );
}

/// The scene's load warnings show in the panel (a window has no terminal for them), and the
/// constraints are counted as the file's records.
#[test]
fn the_panel_shows_the_scenes_warnings() {
    let mut s = session("two-chain", Settings::default());
    let texts = panel_texts(&mut s);
    assert!(
        !texts.iter().any(|t| t.starts_with("warning:")),
        "{texts:?}"
    );
    assert!(
        texts.iter().any(|t| t.contains("16 distance constraints")),
        "{texts:?}"
    );
    let mut world = load("two-chain", Settings::default());
    world.warnings = vec!["m.off: the mesh is not convex".into()];
    let mut s = Session::new(world, SceneSource::named("two-chain"));
    let texts = panel_texts(&mut s);
    assert!(
        texts.contains(&"warning: m.off: the mesh is not convex".to_string()),
        "{texts:?}"
    );
}
