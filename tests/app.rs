//! The app driven through its UI (egui_kittest, no window) and its state: correspondences added,
//! moved and deleted by simulated clicks, one-to-many, undo/redo, parameter edits restarting the
//! transfer, progressive results, cancel, and errors from bad files shown as messages.

#![cfg(feature = "gui")]

mod scratch;
use scratch::Scratch;

use std::sync::Arc;
use std::time::{Duration, Instant};

use eframe::egui::{self, Pos2};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use meshmatch::TriMesh;
use meshmatch::app::{AppParams, MeshMatchApp, Selection};
use meshmatch::correspondence::Correspondence;
use meshmatch::correspondence::Side;
use meshmatch::jobs::worker::{Engine, Solved};
use meshmatch::work::{CancelToken, Event, Progress};

/// Parameters of the test engine.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
struct TestParams {
    iterations: usize,
    step_ms: u64,
}

impl Default for TestParams {
    fn default() -> Self {
        TestParams {
            iterations: 3,
            step_ms: 5,
        }
    }
}

impl AppParams for TestParams {
    fn ui(&mut self, ui: &mut egui::Ui) -> bool {
        ui.add(egui::DragValue::new(&mut self.iterations).prefix("iterations "))
            .changed()
    }
}

/// A test double for the transfer engine: every target vertex takes the source colour of the
/// nearest correspondence (by target-space distance), streaming one partial per iteration.
/// It counts preparations so tests can check the cache.
#[derive(Clone, Default)]
struct TestEngine {
    prepared: Arc<std::sync::atomic::AtomicUsize>,
    /// Number the working mesh's vertices in reverse file order (a working mesh that differs
    /// from the file mesh, as refinement makes it).
    reorder: bool,
}

impl Engine for TestEngine {
    type Params = TestParams;
    type Prepared = Arc<TriMesh>;
    fn prepare_key(&self, _: &TestParams) -> String {
        String::new()
    }
    fn prepare(
        &self,
        mesh: &TriMesh,
        _: &TestParams,
        _: &dyn Fn(Event),
        cancel: &CancelToken,
    ) -> meshmatch::Result<Arc<TriMesh>> {
        cancel.check()?;
        self.prepared
            .fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        Ok(Arc::new(mesh.clone()))
    }
    fn working(&self, p: &Arc<TriMesh>) -> (Arc<TriMesh>, Arc<[u32]>, Arc<[u32]>) {
        let n = p.positions.len() as u32;
        if !self.reorder {
            let ids: Arc<[u32]> = (0..n).collect();
            return (p.clone(), ids.clone(), ids);
        }
        // Working vertex w is file vertex n - 1 - w (the map is its own inverse).
        let ids: Arc<[u32]> = (0..n).rev().collect();
        let mut m = TriMesh::new(
            ids.iter().map(|&f| p.positions[f as usize]).collect(),
            p.faces.iter().map(|f| f.map(|v| n - 1 - v)).collect(),
        );
        m.colors = p
            .colors
            .as_ref()
            .map(|c| ids.iter().map(|&f| c[f as usize]).collect());
        (Arc::new(m), ids.clone(), ids)
    }
    fn solve(
        &self,
        s: &Arc<TriMesh>,
        t: &Arc<TriMesh>,
        corr: &[Correspondence],
        params: &TestParams,
        sink: &dyn Fn(Event),
        cancel: &CancelToken,
    ) -> meshmatch::Result<Solved> {
        let src_cols = s.colors.clone().unwrap_or_default();
        let mut out = vec![[0.5; 3]; t.positions.len()];
        for it in 1..=params.iterations {
            for _ in 0..params.step_ms {
                std::thread::sleep(Duration::from_millis(1));
                cancel.check()?;
            }
            for (v, o) in out.iter_mut().enumerate() {
                let p = glam::Vec3::from(t.positions[v]);
                let best = corr
                    .iter()
                    .flat_map(|c| {
                        c.target_vertices
                            .iter()
                            .map(move |&tv| (c.source_vertex, tv))
                    })
                    .min_by(|a, b| {
                        let da = p.distance(glam::Vec3::from(t.positions[a.1 as usize]));
                        let db = p.distance(glam::Vec3::from(t.positions[b.1 as usize]));
                        da.total_cmp(&db)
                    });
                if let Some((sv, _)) = best {
                    *o = src_cols.get(sv as usize).copied().unwrap_or([0.5; 3]);
                }
            }
            sink(Event::Partial {
                progress: Progress {
                    stage: "solve",
                    iteration: it,
                    levels: 1,
                    fraction: it as f32 / params.iterations as f32,
                    ..Default::default()
                },
                signal: out.clone().into(),
            });
        }
        Ok(Solved {
            working_signal: out.clone(),
            file_signal: out,
            layout: None,
            full: None,
            texture: None,
        })
    }
}

/// A UV sphere (poles on the y axis) with colours red (x > 0) / blue.
fn sphere(rings: u32, segments: u32) -> TriMesh {
    let (positions, faces) = meshmatch::testdata::uv_sphere_y_up(rings as usize, segments as usize);
    let mut m = TriMesh::new(positions, faces);
    m.colors = Some(
        m.positions
            .iter()
            .map(|p| {
                if p[0] > 0.0 {
                    [1.0, 0.0, 0.0]
                } else {
                    [0.0, 0.0, 1.0]
                }
            })
            .collect(),
    );
    m
}

type App = MeshMatchApp<TestEngine>;

fn harness(app: App) -> Harness<'static, App> {
    Harness::builder()
        .with_size(egui::Vec2::new(1200.0, 700.0))
        .with_max_steps(20)
        .build_ui_state(|ui, app: &mut App| app.frame_ui(ui, None), app)
}

fn app_with_spheres() -> App {
    let mut app = App::new(TestEngine::default(), None);
    app.state.set_mesh(Side::Source, sphere(12, 16), false);
    app.state.set_mesh(Side::Target, sphere(16, 24), false);
    // as if opened from files: nothing unsaved yet
    app.state.mark_saved(None);
    app
}

/// Screen position of a file vertex in a view (after at least one frame).
fn vertex_pos(h: &Harness<'static, App>, side: Side, v: u32) -> Pos2 {
    let app = h.state();
    let rect = app.views.rects[if side == Side::Source { 0 } else { 1 }];
    app.views
        .marker_pos(&app.state, side, rect, v)
        .expect("vertex visible")
}

fn click(h: &mut Harness<'static, App>, pos: Pos2, modifiers: egui::Modifiers) {
    h.hover_at(pos);
    h.step();
    for pressed in [true, false] {
        h.event_modifiers(
            egui::Event::PointerButton {
                pos,
                button: egui::PointerButton::Primary,
                pressed,
                modifiers,
            },
            modifiers,
        );
    }
    h.step();
    h.step();
}

/// Click where file vertex `v` of `side` shows.
fn click_vertex(h: &mut Harness<'static, App>, side: Side, v: u32, modifiers: egui::Modifiers) {
    let p = vertex_pos(h, side, v);
    click(h, p, modifiers);
}

/// A vertex facing the default camera (the one nearest to the eye).
fn front_vertex(h: &Harness<'static, App>, side: Side, nth: usize) -> u32 {
    let app = h.state();
    let slot = app.state.slot(side).unwrap();
    let m = slot.displayed();
    let frame = meshmatch::render::Frame::of_points(&m.positions);
    let cam = app.views.cameras[if side == Side::Source { 0 } else { 1 }];
    let (eye, _) = cam.eye_target(&frame);
    let mut order: Vec<u32> = (0..m.positions.len() as u32).collect();
    order.sort_by(|&a, &b| {
        let da = glam::Vec3::from(m.positions[a as usize]).distance(eye);
        let db = glam::Vec3::from(m.positions[b as usize]).distance(eye);
        da.total_cmp(&db)
    });
    // Spread picks out: take every 7th of the nearest vertices.
    order[nth * 7]
}

fn wait_done(h: &mut Harness<'static, App>, job_at_least: u64) {
    let t0 = Instant::now();
    loop {
        h.step();
        let s = &h.state().state;
        if s.job.job >= job_at_least && !s.job.running && !s.restart_pending() && s.result.is_some()
        {
            return;
        }
        assert!(t0.elapsed() < Duration::from_secs(10), "job did not finish");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn clicks_add_pairs_shift_click_adds_targets_delete_and_undo_redo() {
    let mut h = harness(app_with_spheres());
    h.run_steps(3);
    let s0 = front_vertex(&h, Side::Source, 0);
    let t0 = front_vertex(&h, Side::Target, 0);
    let t1 = front_vertex(&h, Side::Target, 3);
    // Source click, then target click: one pair with the clicked vertices.
    click_vertex(&mut h, Side::Source, s0, egui::Modifiers::NONE);
    assert_eq!(h.state().state.pending_source, Some(s0));
    click_vertex(&mut h, Side::Target, t0, egui::Modifiers::NONE);
    assert_eq!(
        h.state().state.corr,
        vec![Correspondence {
            source_vertex: s0,
            target_vertices: vec![t0]
        }]
    );
    // Shift-click another target point: one-to-many.
    click_vertex(&mut h, Side::Target, t1, egui::Modifiers::SHIFT);
    assert_eq!(h.state().state.corr[0].target_vertices, vec![t0, t1]);
    // Click the first target marker to select it, Delete removes that target only.
    click_vertex(&mut h, Side::Target, t0, egui::Modifiers::NONE);
    assert_eq!(
        h.state().state.selected,
        Some(Selection {
            pair: 0,
            side: Side::Target,
            k: 0
        })
    );
    h.key_press(egui::Key::Delete);
    h.step();
    assert_eq!(h.state().state.corr[0].target_vertices, vec![t1]);
    // Undo restores it, redo removes it again.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.step();
    assert_eq!(h.state().state.corr[0].target_vertices, vec![t0, t1]);
    h.key_press_modifiers(
        egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
        egui::Key::Z,
    );
    h.step();
    assert_eq!(h.state().state.corr[0].target_vertices, vec![t1]);
    // Selecting the source marker and deleting removes the whole pair.
    click_vertex(&mut h, Side::Source, s0, egui::Modifiers::NONE);
    h.key_press(egui::Key::Delete);
    h.step();
    assert!(h.state().state.corr.is_empty());
    // Undo twice walks back through the history.
    assert!(h.state_mut().state.undo());
    assert_eq!(h.state().state.corr.len(), 1);
    assert!(h.state_mut().state.undo());
    assert_eq!(h.state().state.corr[0].target_vertices, vec![t0, t1]);
}

#[test]
fn dragging_a_marker_moves_it_and_one_undo_restores_it() {
    let mut h = harness(app_with_spheres());
    h.run_steps(3);
    let s0 = front_vertex(&h, Side::Source, 0);
    let t0 = front_vertex(&h, Side::Target, 0);
    let t_new = front_vertex(&h, Side::Target, 6);
    click_vertex(&mut h, Side::Source, s0, egui::Modifiers::NONE);
    click_vertex(&mut h, Side::Target, t0, egui::Modifiers::NONE);
    let (undo_before, _) = h.state().state.history_len();
    // Press on the marker, move in steps to the new vertex, release.
    let from = vertex_pos(&h, Side::Target, t0);
    let to = vertex_pos(&h, Side::Target, t_new);
    h.drag_at(from);
    h.step();
    for k in 1..=8 {
        h.hover_at(from + (to - from) * (k as f32 / 8.0));
        h.step();
    }
    h.drop_at(to);
    h.step();
    let cams = h.state().views.cameras;
    assert_eq!(h.state().state.corr[0].target_vertices, vec![t_new]);
    // The drag moved the marker, not the camera.
    assert_eq!(cams[1], meshmatch::render::Camera::default());
    assert_eq!(h.state().state.history_len().0, undo_before + 1);
    h.state_mut().state.undo();
    assert_eq!(h.state().state.corr[0].target_vertices, vec![t0]);
}

#[test]
fn orbit_drag_moves_both_locked_cameras() {
    let mut h = harness(app_with_spheres());
    h.run_steps(3);
    let rect = h.state().views.rects[0];
    // Drag on empty background (corner of the source view) orbits.
    let from = rect.left_top() + egui::vec2(20.0, 40.0);
    h.drag_at(from);
    h.step();
    for k in 1..=5 {
        h.hover_at(from + egui::vec2(20.0 * k as f32, 0.0));
        h.step();
    }
    h.drop_at(from + egui::vec2(100.0, 0.0));
    h.step();
    let cams = h.state().views.cameras;
    assert_ne!(cams[0], meshmatch::render::Camera::default());
    assert_eq!(cams[0], cams[1]);
    assert!(h.state().state.corr.is_empty());
}

#[test]
fn transfer_streams_partials_and_a_parameter_edit_restarts_only_solve() {
    let engine = TestEngine::default();
    let prepared = engine.prepared.clone();
    let mut app = App::new(engine, None);
    app.state.set_mesh(Side::Source, sphere(12, 16), false);
    app.state.set_mesh(Side::Target, sphere(16, 24), false);
    app.state
        .set_correspondences(vec![Correspondence {
            source_vertex: 20,
            target_vertices: vec![30],
        }])
        .unwrap();
    let mut h = harness(app);
    wait_done(&mut h, 1);
    let first_job = h.state().state.job.job;
    assert!(h.state().state.job.partials >= 1);
    assert_eq!(prepared.load(std::sync::atomic::Ordering::SeqCst), 2);
    // The target colours are the streamed result (source vertex 20 is red or blue, not grey).
    let slot = h.state().state.slot(Side::Target).unwrap();
    assert!(slot.base_colors.iter().all(|c| *c != [0.5, 0.5, 0.5]));
    // A parameter edit (through the state, as the panel's editor does) starts a new job after the
    // debounce delay; the meshes are not prepared again.
    let mut p = h.state().state.params.clone();
    p.iterations = 4;
    h.state_mut().state.set_params(p, Instant::now());
    assert!(h.state().state.restart_pending());
    wait_done(&mut h, first_job + 1);
    assert!(h.state().state.job.job > first_job);
    assert_eq!(h.state().state.job.partials, 4);
    assert_eq!(prepared.load(std::sync::atomic::Ordering::SeqCst), 2);
}

#[test]
fn cancel_stops_a_running_job_quickly() {
    let mut app = app_with_spheres();
    app.state.params = TestParams {
        iterations: 100,
        step_ms: 50,
    };
    app.state
        .schedule_restart(Instant::now() - Duration::from_secs(1));
    app.pump(Instant::now());
    assert!(app.state.job.running);
    std::thread::sleep(Duration::from_millis(100));
    app.state.cancel_job();
    let t0 = Instant::now();
    app.pump(Instant::now());
    while app.state.job.running {
        assert!(
            app.wait_events(Duration::from_millis(500)),
            "no event after cancel"
        );
    }
    let dt = t0.elapsed();
    assert_eq!(app.state.job.outcome, "cancelled");
    assert!(dt < Duration::from_millis(100), "cancel took {dt:?}");
}

#[test]
fn a_bad_file_shows_a_dismissable_error_and_the_app_keeps_running() {
    let dir = Scratch::new("app");
    let bad = dir.join("broken.ply");
    std::fs::write(
        &bad,
        b"ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n",
    )
    .unwrap();
    let mut h = harness(app_with_spheres());
    h.run_steps(2);
    let r = h.state_mut().state.open_mesh(Side::Target, &bad);
    assert!(r.is_err());
    h.state_mut().state.report(r.unwrap_err());
    // A missing session and a non-mesh file are errors too.
    let r = h.state_mut().state.open_session(&dir.join("missing.json"));
    h.state_mut().state.report(r.unwrap_err());
    h.run_steps(3);
    assert_eq!(h.state().state.errors.len(), 2);
    // The meshes are untouched and the error window is shown with a Dismiss button.
    assert_eq!(
        h.state()
            .state
            .slot(Side::Target)
            .unwrap()
            .file
            .positions
            .len(),
        sphere(16, 24).positions.len()
    );
    h.get_by_label("Dismiss").click();
    h.run_steps(2);
    assert!(h.state().state.errors.is_empty());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn session_round_trip_keeps_correspondences_and_params() {
    let dir = Scratch::new("session");
    let (src, tgt) = (dir.join("src.ply"), dir.join("tgt.ply"));
    meshmatch::mesh::io::save(&sphere(10, 12), &src).unwrap();
    meshmatch::mesh::io::save(&sphere(12, 14), &tgt).unwrap();
    let mut app = App::new(TestEngine::default(), None);
    app.state.open_mesh(Side::Source, &src).unwrap();
    app.state.open_mesh(Side::Target, &tgt).unwrap();
    let corr = vec![
        Correspondence {
            source_vertex: 3,
            target_vertices: vec![5, 9],
        },
        Correspondence {
            source_vertex: 40,
            target_vertices: vec![60],
        },
    ];
    app.state.set_correspondences(corr.clone()).unwrap();
    app.state.params.iterations = 7;
    app.state.paint_at(Side::Target, [1.0, 0.0, 0.0], true);
    let session = dir.join("s.json");
    app.state.save_session(&session).unwrap();
    let text = std::fs::read_to_string(&session).unwrap();
    assert!(text.contains("\"correspondences\""));
    let mut b = App::new(TestEngine::default(), None);
    b.state.open_session(&session).unwrap();
    assert_eq!(b.state.corr, corr);
    assert_eq!(b.state.params.iterations, 7);
    assert!(dir.join("s.target_paint.ply").exists());
    // Out-of-range correspondences are refused with an error.
    assert!(
        b.state
            .set_correspondences(vec![Correspondence {
                source_vertex: 1_000_000,
                target_vertices: vec![0],
            }])
            .is_err()
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn painting_colours_vertices_near_the_brush_and_undo_removes_the_stroke() {
    let mut app = app_with_spheres();
    app.state.brush.color = [0.0, 1.0, 0.0];
    app.state.brush.radius = 0.3;
    app.state.brush.hardness = 1.0;
    let n = app.state.paint_at(Side::Source, [0.0, 1.0, 0.0], true);
    assert!(n > 0);
    let cols = app.state.slot(Side::Source).unwrap().display_colors();
    let top = &cols[0];
    assert!(top[1] > 0.99 && top[0] < 0.01, "{top:?}");
    let bottom = cols.last().unwrap();
    assert!(bottom[1] < 0.01);
    app.state.brush.eraser = true;
    app.state.paint_at(Side::Source, [0.0, 1.0, 0.0], true);
    let cols = app.state.slot(Side::Source).unwrap().display_colors();
    assert!(cols[0][1] < 0.01);
    app.state.undo();
    let cols = app.state.slot(Side::Source).unwrap().display_colors();
    assert!(cols[0][1] > 0.99);
    app.state.undo();
    assert!(app.state.slot(Side::Source).unwrap().paint.is_none());
}

#[test]
fn help_overlay_toggles_with_h_and_the_question_button() {
    let mut h = harness(app_with_spheres());
    h.run_steps(2);
    assert!(h.query_by_label_contains("Orbit: left-drag").is_none());
    h.get_by_label("?").click();
    h.run_steps(2);
    assert!(h.query_by_label_contains("Orbit: left-drag").is_some());
    h.key_press(egui::Key::H);
    h.run_steps(2);
    assert!(h.query_by_label_contains("Orbit: left-drag").is_none());
}

#[test]
fn complete_from_paint_fills_the_rest_from_the_painted_example_and_undo_restores() {
    let mut app = App::new(TestEngine::default(), None);
    app.state.set_mesh(Side::Source, sphere(12, 16), false);
    app.state.set_mesh(Side::Target, sphere(40, 48), false);
    // Nothing painted yet: a clear error, nothing runs.
    app.start_tool("complete-target");
    assert!(app.tool.is_none());
    assert!(
        app.state
            .errors
            .iter()
            .any(|e| e.contains("paint part of the mesh"))
    );
    // Paint the upper half in green and yellow bands.
    app.state.brush.radius = 0.12;
    app.state.brush.hardness = 1.0;
    let positions = app
        .state
        .slot(Side::Target)
        .unwrap()
        .displayed()
        .positions
        .clone();
    for (i, p) in positions.iter().enumerate() {
        if p[1] > 0.05 && i % 3 == 0 {
            app.state.brush.color = if (p[1] * 8.0) as i32 % 2 == 0 {
                [0.0, 0.8, 0.0]
            } else {
                [1.0, 1.0, 0.0]
            };
            app.state.paint_at(Side::Target, *p, i == 0);
        }
    }
    let before = app.state.slot(Side::Target).unwrap().paint.clone().unwrap();
    let painted: Vec<bool> = before.iter().map(|p| p[3] >= 0.5).collect();
    let np = painted.iter().filter(|x| **x).count();
    assert!(
        np > positions.len() / 4 && np < positions.len(),
        "{np} painted"
    );
    app.start_tool("complete-target");
    let outcome = app.tool.as_ref().expect("completion started").wait();
    let outcome = outcome.expect("completion succeeded");
    app.state.apply_tool_outcome(outcome);
    let after = app.state.slot(Side::Target).unwrap().paint.clone().unwrap();
    // Painted vertices keep their colours; every other vertex now carries the example's
    // green or yellow, not the sphere's own blue or red.
    let mut like_example = 0;
    let mut filled = 0;
    for v in 0..after.len() {
        assert_eq!(after[v][3], 1.0);
        if painted[v] {
            assert_eq!(
                &after[v][..3],
                &before[v][..3],
                "painted vertex {v} changed"
            );
        } else {
            filled += 1;
            let c = &after[v];
            if c[1] > 0.5 && c[2] < 0.3 {
                like_example += 1;
            }
        }
    }
    assert!(
        like_example * 10 >= filled * 9,
        "{like_example} of {filled} completed vertices look like the painted example"
    );
    // One undo step takes the completion back.
    app.state.undo();
    let restored = app.state.slot(Side::Target).unwrap().paint.clone().unwrap();
    assert_eq!(restored, before);
}

#[test]
fn paint_with_exemplar_streams_partials_resembles_the_exemplar_and_undo_restores() {
    use meshmatch::app::tools::{ExemplarSettings, Region, load_exemplar};
    let image = meshmatch::testdata::data_path("textures/bricks.png");
    let mut app = App::new(TestEngine::default(), None);
    app.state.set_mesh(Side::Source, sphere(12, 16), false);
    app.state.set_mesh(Side::Target, sphere(40, 48), false);
    let mut h = harness(app);
    // Let the worker prepare the meshes (the view then shows the target in its default grey).
    let t0 = Instant::now();
    while h
        .state()
        .state
        .slot(Side::Target)
        .unwrap()
        .working
        .is_none()
    {
        h.step();
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "target not prepared"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    // ...and the transfer started on the new meshes finish (its result recolours the target: on
    // a busy machine it could land after `before` below).
    while {
        let s = &h.state().state;
        s.restart_pending() || s.job.running || s.job.job == 0
    } {
        h.step();
        assert!(t0.elapsed() < Duration::from_secs(30), "transfer not done");
        std::thread::sleep(Duration::from_millis(10));
    }
    h.run_steps(2);
    let before = h.state().state.slot(Side::Target).unwrap().display_colors();
    let n = before.len();
    // The exemplar as the tool uses it (shrunk to the default 64 px width).
    let settings = ExemplarSettings {
        image: Some(image.clone()),
        scale: 0.5,
        ..ExemplarSettings::default()
    };
    assert_eq!(settings.region, Region::Whole);
    assert_eq!(settings.side, Side::Target);
    let (ex, alpha) = load_exemplar(&image, settings.pixels).unwrap();
    assert_eq!(ex.width(), settings.pixels);
    // The bricks have a transparent hole: it never shows, so the exemplar's colours are its
    // opaque pixels.
    let alpha = alpha.expect("bricks.png has a transparent hole");
    let mean = |c: &[[f32; 3]]| {
        c.iter()
            .fold([0.0f32; 3], |a, x| [a[0] + x[0], a[1] + x[1], a[2] + x[2]])
            .map(|s| s / c.len().max(1) as f32)
    };
    let dist = |a: [f32; 3], b: [f32; 3]| {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    let ex_colors: Vec<[f32; 3]> = meshmatch::synthesis::exemplar::image_colors(&ex)
        .into_iter()
        .zip(alpha.pixels())
        .filter(|(_, a)| a.0[0] >= 128)
        .map(|(c, _)| c)
        .collect();
    let ex_mean = mean(&ex_colors);
    let old_mean = mean(&before);
    // (The opaque bricks average 0.12 from the old grey: still well beyond the 0.08 the output
    // must come within, so the check below cannot pass on unchanged colours.)
    assert!(
        dist(ex_mean, old_mean) > 0.1,
        "the exemplar ({ex_mean:?}) must differ from the old colours ({old_mean:?})"
    );
    let palette: std::collections::HashSet<[u8; 3]> = ex.pixels().map(|p| p.0).collect();
    let to_u8 = |c: [f32; 3]| c.map(|x| (x * 255.0).round().clamp(0.0, 255.0) as u8);

    // Drive the tool through its window: the image is already chosen, the user clicks Run.
    h.state_mut().open_exemplar_dialog(Some(image.clone()));
    h.state_mut()
        .system_mut::<meshmatch::app::tools::ExemplarDialog>()
        .unwrap()
        .settings
        .scale = 0.5;
    h.run_steps(2);
    assert!(h.query_by_label_contains("Paint with exemplar").is_some());
    h.get_by_label("Run").click();
    h.step();
    assert!(h.state().tool.is_some(), "the tool started");
    assert!(
        !h.state()
            .system::<meshmatch::app::tools::ExemplarDialog>()
            .unwrap()
            .open,
        "the window closes on Run"
    );
    // Partial results show in the view while the tool runs (no undo step for them).
    let mut previews = 0;
    let mut last_preview: Option<Vec<[f32; 3]>> = None;
    let t0 = Instant::now();
    while h.state().tool.is_some() {
        h.step();
        let app = h.state();
        if app.tool.is_some() {
            let cols = app.state.slot(Side::Target).unwrap().display_colors();
            if cols != before && last_preview.as_ref() != Some(&cols) {
                previews += 1;
                last_preview = Some(cols);
            }
            assert_eq!(
                app.state.history_len().0,
                0,
                "a preview is not an undo step"
            );
        }
        assert!(
            t0.elapsed() < Duration::from_secs(120),
            "synthesis did not finish"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    h.run_steps(2);
    assert!(
        h.state().state.errors.is_empty(),
        "{:?}",
        h.state().state.errors
    );
    assert!(previews >= 1, "no partial result was shown while it ran");
    let after = h.state().state.slot(Side::Target).unwrap().display_colors();
    assert_eq!(after.len(), n);
    // Every vertex changed and carries a colour of the exemplar; the mean colour is the
    // exemplar's, far from the old one.
    let changed = after.iter().zip(&before).filter(|(a, b)| a != b).count();
    assert!(changed * 100 >= n * 95, "{changed} of {n} vertices changed");
    let in_palette = after
        .iter()
        .filter(|c| palette.contains(&to_u8(**c)))
        .count();
    assert!(
        in_palette * 100 >= n * 99,
        "{in_palette} of {n} vertices carry an exemplar colour"
    );
    let out_mean = mean(&after);
    println!("mean colour: exemplar {ex_mean:?}, output {out_mean:?}, old {old_mean:?}");
    assert!(
        dist(out_mean, ex_mean) < 0.08,
        "output mean {out_mean:?} vs exemplar {ex_mean:?}"
    );
    assert!(dist(out_mean, old_mean) > 0.5 * dist(ex_mean, old_mean));
    assert!(h.state().state.message.contains("bricks.png"));
    // One undo takes the whole result back.
    assert_eq!(h.state().state.history_len().0, 1);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run_steps(2);
    let undone = h.state().state.slot(Side::Target).unwrap().display_colors();
    assert_eq!(undone, before);

    // Cancel during a run: the preview goes away, the colours and the history are as before.
    let history = h.state().state.history_len();
    h.state_mut().start_exemplar(&settings);
    let t0 = Instant::now();
    while h.state().state.slot(Side::Target).unwrap().display_colors() == before {
        h.step();
        assert!(h.state().tool.is_some(), "finished before a preview showed");
        assert!(t0.elapsed() < Duration::from_secs(120), "no preview");
        std::thread::sleep(Duration::from_millis(5));
    }
    h.state().tool.as_ref().unwrap().cancel.cancel();
    let t0 = Instant::now();
    while h.state().tool.is_some() {
        h.step();
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "cancel was not honoured"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    h.run_steps(2);
    assert!(h.state().state.message.contains("cancelled"));
    assert_eq!(
        h.state().state.slot(Side::Target).unwrap().display_colors(),
        before
    );
    assert_eq!(h.state().state.history_len(), history);

    // Painted region only: the rest keeps its colours exactly.
    {
        let st = &mut h.state_mut().state;
        st.brush.radius = 0.3;
        st.brush.hardness = 1.0;
        st.brush.color = [0.0, 0.0, 1.0];
        st.paint_at(Side::Target, [0.0, 1.0, 0.0], true);
    }
    let painted_before = h.state().state.slot(Side::Target).unwrap().display_colors();
    let painted: Vec<bool> = h
        .state()
        .state
        .paint_coverage(Side::Target)
        .unwrap()
        .iter()
        .map(|&c| c >= 0.5)
        .collect();
    let np = painted.iter().filter(|p| **p).count();
    assert!(np > 10 && np < n / 2, "{np} painted");
    let region = ExemplarSettings {
        region: Region::Painted,
        ..settings.clone()
    };
    h.state_mut().start_exemplar(&region);
    let job = h.state_mut().tool.take().expect("started");
    let out = job.wait().unwrap();
    h.state_mut().state.apply_tool_outcome(out);
    let cols = h.state().state.slot(Side::Target).unwrap().display_colors();
    let mut region_in_palette = 0;
    for v in 0..n {
        if painted[v] {
            region_in_palette += palette.contains(&to_u8(cols[v])) as usize;
        } else {
            assert_eq!(
                to_u8(cols[v]),
                to_u8(painted_before[v]),
                "vertex {v} outside"
            );
        }
    }
    assert!(
        region_in_palette * 100 >= np * 99,
        "{region_in_palette} of {np} painted vertices carry an exemplar colour"
    );

    // A file that is not an image: a dismissable error, no panic, colours untouched.
    let scratch = Scratch::new("not_image");
    let bad = scratch.join("not_image.png");
    std::fs::write(&bad, b"not an image").unwrap();
    let shown = h.state().state.slot(Side::Target).unwrap().display_colors();
    h.state_mut().open_exemplar_dialog(Some(bad.clone()));
    h.run_steps(2);
    h.get_by_label("Run").click();
    h.step();
    assert!(h.state().tool.is_some(), "the tool started");
    let t0 = Instant::now();
    while h.state().tool.is_some() {
        h.step();
        assert!(t0.elapsed() < Duration::from_secs(10));
        std::thread::sleep(Duration::from_millis(10));
    }
    h.run_steps(2);
    let errors = &h.state().state.errors;
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(errors[0].contains("cannot decode image"), "{errors:?}");
    assert_eq!(
        h.state().state.slot(Side::Target).unwrap().display_colors(),
        shown
    );
    h.get_by_label("Dismiss").click();
    h.run_steps(2);
    assert!(h.state().state.errors.is_empty());
    std::fs::remove_file(&bad).ok();
}

/// Send pending meshes to the worker and wait until both sides show their working meshes.
fn wait_prepared(app: &mut App) {
    let t0 = Instant::now();
    app.pump(Instant::now());
    while !app
        .state
        .meshes
        .iter()
        .all(|m| m.as_ref().is_some_and(|s| s.working.is_some()))
    {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "meshes were not prepared"
        );
        app.wait_events(Duration::from_millis(50));
        app.pump(Instant::now());
    }
}

fn reordering_app() -> App {
    App::new(
        TestEngine {
            reorder: true,
            ..Default::default()
        },
        None,
    )
}

fn temp_dir(name: &str) -> Scratch {
    Scratch::new(name)
}

/// A sphere with (constant) UVs, so that a texture can be applied to it.
fn uv_sphere(rings: u32, segments: u32) -> TriMesh {
    let mut m = sphere(rings, segments);
    m.uvs = Some(vec![[0.25, 0.75]; 3 * m.faces.len()]);
    m
}

fn spheres_scene() -> meshmatch::Result<meshmatch::app::DemoScene> {
    Ok(meshmatch::app::DemoScene {
        source: uv_sphere(10, 12),
        target: sphere(12, 14),
        correspondences: vec![
            Correspondence {
                source_vertex: 4,
                target_vertices: vec![7],
            },
            Correspondence {
                source_vertex: 50,
                target_vertices: vec![70, 71],
            },
        ],
    })
}

fn app_with_scene(engine: TestEngine) -> App {
    App::new(engine, None).with_demo_scenes(vec![(
        "Two spheres".to_string(),
        spheres_scene as fn() -> meshmatch::Result<meshmatch::app::DemoScene>,
    )])
}

#[test]
fn opening_a_session_brings_back_the_painted_colours_on_the_working_mesh() {
    let dir = temp_dir("paint_session");
    let (src, tgt) = (dir.join("src.ply"), dir.join("tgt.ply"));
    meshmatch::mesh::io::save(&sphere(10, 12), &src).unwrap();
    meshmatch::mesh::io::save(&sphere(16, 20), &tgt).unwrap();
    let mut a = reordering_app();
    a.state.open_mesh(Side::Source, &src).unwrap();
    a.state.open_mesh(Side::Target, &tgt).unwrap();
    wait_prepared(&mut a);
    a.state.brush.color = [0.0, 1.0, 0.0];
    a.state.brush.radius = 0.3;
    a.state.brush.hardness = 0.3;
    a.state.paint_at(Side::Target, [0.0, 1.0, 0.0], true);
    a.state.brush.color = [1.0, 1.0, 0.0];
    a.state.paint_at(Side::Source, [0.0, -1.0, 0.0], true);
    let want =
        [Side::Source, Side::Target].map(|s| a.state.slot(s).unwrap().paint.clone().unwrap());
    let session = dir.join("s.json");
    a.state.save_session(&session).unwrap();

    let mut b = reordering_app();
    b.state.open_session(&session).unwrap();
    // Shown at once on the file meshes (file order: the reverse of the working order)...
    let tslot = b.state.slot(Side::Target).unwrap();
    let n = tslot.file.positions.len();
    let shown = tslot
        .paint
        .clone()
        .expect("target paint restored on opening");
    for f in 0..n {
        let w = &want[1][n - 1 - f];
        for k in 0..4 {
            assert!(
                (shown[f][k] - w[k]).abs() <= 1.0 / 255.0,
                "file vertex {f}: {:?} vs {w:?}",
                shown[f]
            );
        }
    }
    // ...and on the working meshes once they are prepared.
    wait_prepared(&mut b);
    for (i, side) in [Side::Source, Side::Target].into_iter().enumerate() {
        let got = b
            .state
            .slot(side)
            .unwrap()
            .paint
            .clone()
            .expect("paint kept");
        assert_eq!(got.len(), want[i].len());
        for (g, w) in got.iter().zip(&want[i]) {
            for k in 0..4 {
                assert!(
                    (g[k] - w[k]).abs() <= 1.0 / 255.0,
                    "{side:?}: {g:?} vs {w:?}"
                );
            }
        }
        let painted = got.iter().filter(|p| p[3] > 0.99).count();
        assert!(
            painted > 0 && painted < got.len(),
            "{side:?}: {painted} painted"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_session_saved_from_a_built_in_scene_reopens_the_scene_with_its_texture() {
    let dir = temp_dir("scene_session");
    let tex = dir.join("tex.png");
    image::RgbImage::from_pixel(4, 4, image::Rgb([10, 200, 30]))
        .save(&tex)
        .unwrap();
    let mut a = app_with_scene(TestEngine::default());
    a.startup(&meshmatch::app::Startup::default());
    a.state.open_texture(&tex).unwrap();
    let edited = vec![Correspondence {
        source_vertex: 9,
        target_vertices: vec![11, 12],
    }];
    a.state.set_correspondences(edited.clone()).unwrap();
    let session = dir.join("scene.json");
    a.state.save_session(&session).unwrap();
    let text = std::fs::read_to_string(&session).unwrap();
    assert!(text.contains("\"source_scene\": \"Two spheres\""), "{text}");

    let mut b = app_with_scene(TestEngine::default());
    b.state.open_session(&session).unwrap();
    assert_eq!(b.state.corr, edited);
    let want = spheres_scene().unwrap();
    for (side, m) in [(Side::Source, &want.source), (Side::Target, &want.target)] {
        let slot = b.state.slot(side).unwrap();
        assert_eq!(slot.file.positions, m.positions);
        assert_eq!(slot.scene.as_deref(), Some("Two spheres"));
    }
    let src = b.state.slot(Side::Source).unwrap();
    assert!(src.file.texture.is_some(), "texture re-applied");
    assert_eq!(
        src.texture_file.as_deref(),
        Some(std::path::absolute(&tex).unwrap().as_path())
    );
    // The reopened session saves the same way again.
    b.state.save_session(&dir.join("again.json")).unwrap();
    // A computed mesh (no file, no scene) is saved beside the session rather than as null.
    let mut c = App::new(TestEngine::default(), None);
    c.state.set_mesh(Side::Source, sphere(8, 8), false);
    c.state.save_session(&dir.join("computed.json")).unwrap();
    let mut d = App::new(TestEngine::default(), None);
    d.state.open_session(&dir.join("computed.json")).unwrap();
    assert_eq!(
        d.state.slot(Side::Source).unwrap().file.positions,
        sphere(8, 8).positions
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn paint_survives_preparation_and_undo_never_applies_a_stale_layer() {
    let mut app = reordering_app();
    app.state.set_mesh(Side::Source, sphere(12, 16), false);
    app.state.set_mesh(Side::Target, sphere(16, 24), false);
    app.state.brush.radius = 0.3;
    app.state.brush.hardness = 1.0;
    // Two strokes on the file mesh, before the worker prepared it.
    assert!(app.state.slot(Side::Source).unwrap().working.is_none());
    app.state.brush.color = [0.0, 1.0, 0.0];
    app.state.paint_at(Side::Source, [0.0, 1.0, 0.0], true);
    app.state.brush.color = [1.0, 0.0, 1.0];
    app.state.paint_at(Side::Source, [0.0, -1.0, 0.0], true);
    wait_prepared(&mut app);
    let slot = app.state.slot(Side::Source).unwrap();
    let n = slot.displayed().num_vertices();
    // Working vertex 0 is the south pole (file vertex n - 1), the last one the north pole.
    assert_eq!(slot.displayed().positions[0], [0.0, -1.0, 0.0]);
    let cols = slot.display_colors();
    assert_eq!(cols.len(), n);
    assert_eq!(cols[n - 1], [0.0, 1.0, 0.0], "north stroke kept");
    assert_eq!(cols[0], [1.0, 0.0, 1.0], "south stroke kept");
    // Undo takes the second stroke back, on the working mesh.
    assert!(app.state.undo());
    let slot = app.state.slot(Side::Source).unwrap();
    assert_eq!(slot.paint.as_ref().unwrap().len(), n);
    let cols = slot.display_colors();
    assert_eq!(cols[n - 1], [0.0, 1.0, 0.0]);
    assert_eq!(
        cols[0],
        [0.0, 0.0, 1.0],
        "south stroke undone (the sphere's blue)"
    );
    assert!(app.state.redo());
    assert_eq!(
        app.state.slot(Side::Source).unwrap().display_colors()[0],
        [1.0, 0.0, 1.0]
    );
}

/// A file dropped on the window (the harness has no real file handles).
#[derive(Debug)]
struct Dropped(std::path::PathBuf);

impl egui::DroppedFile for Dropped {
    fn path(&self) -> &std::path::Path {
        &self.0
    }
    fn bytes(&self) -> Result<Vec<u8>, String> {
        std::fs::read(&self.0).map_err(|e| e.to_string())
    }
}

fn drop_file(h: &mut Harness<'static, App>, path: &std::path::Path) {
    h.input_mut()
        .dropped_files
        .push(Arc::new(Dropped(path.to_path_buf())));
    h.step();
    h.step();
}

#[test]
fn dropped_files_open_by_kind_even_without_a_pointer_position() {
    let dir = temp_dir("drop");
    let mesh = dir.join("big.ply");
    meshmatch::mesh::io::save(&uv_sphere(20, 30), &mesh).unwrap();
    let corr = dir.join("corr.json");
    meshmatch::correspondence::CorrespondenceFile {
        correspondences: vec![Correspondence {
            source_vertex: 2,
            target_vertices: vec![3],
        }],
        ..Default::default()
    }
    .save(&corr)
    .unwrap();
    let tex = dir.join("t.png");
    image::RgbImage::from_pixel(2, 2, image::Rgb([200, 0, 0]))
        .save(&tex)
        .unwrap();
    let mut h = harness(app_with_spheres());
    h.run_steps(2);
    // No pointer position at all: the mesh goes to the target.
    assert!(
        h.state()
            .state
            .slot(Side::Target)
            .unwrap()
            .file
            .path
            .is_none()
    );
    drop_file(&mut h, &mesh);
    let n = uv_sphere(20, 30).positions.len();
    assert_eq!(
        h.state()
            .state
            .slot(Side::Target)
            .unwrap()
            .file
            .positions
            .len(),
        n
    );
    // A JSON without parameters is a correspondence file.
    drop_file(&mut h, &corr);
    assert_eq!(h.state().state.corr.len(), 1);
    // After the pointer was over the source and left the window, drops go to the source.
    let src_centre = h.state().views.rects[0].center();
    h.hover_at(src_centre);
    h.step();
    h.event(egui::Event::PointerGone);
    h.step();
    drop_file(&mut h, &mesh);
    // The pair would go with the replaced source: the app asks first; Don't save goes on.
    h.run_steps(2);
    assert!(
        h.query_by_label_contains("Save your work before opening big.ply")
            .is_some()
    );
    h.get_by_label("Don't save").click();
    h.run_steps(2);
    assert_eq!(
        h.state()
            .state
            .slot(Side::Source)
            .unwrap()
            .file
            .positions
            .len(),
        n
    );
    // An image becomes that side's texture, not a mesh (the pointer went to the prompt's button
    // over the target: back over the source first).
    h.hover_at(src_centre);
    h.step();
    h.event(egui::Event::PointerGone);
    h.step();
    drop_file(&mut h, &tex);
    let src = h.state().state.slot(Side::Source).unwrap();
    assert!(src.file.texture.is_some());
    assert_eq!(src.file.positions.len(), n);
    assert!(
        h.state().state.errors.is_empty(),
        "{:?}",
        h.state().state.errors
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn recent_files_persist_across_runs_and_keep_textures_apart_from_meshes() {
    let dir = temp_dir("recent");
    let store = dir.join("config").join("recent.json");
    let mesh = dir.join("m.ply");
    meshmatch::mesh::io::save(&uv_sphere(8, 10), &mesh).unwrap();
    let tex = dir.join("t.png");
    image::RgbImage::from_pixel(2, 2, image::Rgb([0, 0, 200]))
        .save(&tex)
        .unwrap();
    let mut a = App::new(TestEngine::default(), None);
    a.state.load_recent(store.clone());
    a.state.open_mesh(Side::Source, &mesh).unwrap();
    a.state.open_texture(&tex).unwrap();
    drop(a);
    // A later run reads the list back.
    let mut b = App::new(TestEngine::default(), None);
    b.state.load_recent(store);
    use meshmatch::app::state::RecentKind;
    let kinds: Vec<(std::path::PathBuf, RecentKind)> = b
        .state
        .recent
        .iter()
        .map(|r| (r.path.clone(), r.kind))
        .collect();
    assert_eq!(
        kinds,
        vec![
            (std::path::absolute(&tex).unwrap(), RecentKind::Texture),
            (std::path::absolute(&mesh).unwrap(), RecentKind::Mesh),
        ]
    );
    // The menu offers the texture as a texture, not "as source"/"as target".
    b.state.set_mesh(Side::Source, uv_sphere(8, 10), false);
    let mut h = harness(b);
    h.run_steps(2);
    h.get_by_label("File").click();
    h.run_steps(2);
    h.get_by_label("Recent").hover();
    h.run_steps(3);
    assert!(h.query_by_label_contains("Source texture").is_some());
    assert_eq!(h.query_all_by_label("as source").count(), 1);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_single_click_in_paint_mode_paints_one_dab() {
    let mut h = harness(app_with_spheres());
    h.run_steps(3);
    h.state_mut().views.tool = meshmatch::app::Tool::Paint;
    h.state_mut().state.brush.color = [0.0, 1.0, 0.0];
    h.state_mut().state.brush.radius = 0.2;
    h.run_steps(1);
    let v = front_vertex(&h, Side::Source, 0);
    let p = vertex_pos(&h, Side::Source, v);
    let (undo_before, _) = h.state().state.history_len();
    click(&mut h, p, egui::Modifiers::NONE);
    let slot = h.state().state.slot(Side::Source).unwrap();
    let paint = slot.paint.as_ref().expect("the click painted");
    assert!(paint[v as usize][3] > 0.5, "{:?}", paint[v as usize]);
    assert_eq!(h.state().state.history_len().0, undo_before + 1);
    assert!(h.state().state.corr.is_empty() && h.state().state.pending_source.is_none());
}

/// Standard deviation of the distance of the vertices from the origin.
fn radial_std(m: &TriMesh) -> f64 {
    let r: Vec<f64> = m
        .positions
        .iter()
        .map(|p| glam::Vec3::from(*p).length() as f64)
        .collect();
    let mean = r.iter().sum::<f64>() / r.len() as f64;
    (r.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / r.len() as f64).sqrt()
}

#[test]
fn signal_detail_transfers_geometry_at_the_chosen_strength() {
    // Source: a dense unit sphere with fine bumps (a wavelength of a few edges); target: a
    // smooth unit sphere.
    let mut bumpy = sphere(130, 250);
    for p in &mut bumpy.positions {
        let v = glam::Vec3::from(*p);
        let b = 1.0 + 0.02 * (50.0 * v.x).sin() * (50.0 * v.y).sin() * (50.0 * v.z).sin();
        *p = (v * b).to_array();
    }
    let s_src = radial_std(&bumpy);
    let target = sphere(100, 200);
    let mut app = App::new(TestEngine::default(), None);
    app.state.set_mesh(Side::Source, bumpy, false);
    app.state.set_mesh(Side::Target, target.clone(), false);
    let mut h = harness(app);
    h.run_steps(3);
    // The panel offers the detail transfer only once "detail" is the chosen signal.
    assert!(h.query_by_label("Transfer detail").is_none());
    h.get_by_label("detail").click();
    h.run_steps(3);
    assert_eq!(
        h.state().signal.signal,
        meshmatch::app::tools::Signal::Detail
    );
    h.state_mut().signal.strength = 2.0;
    h.get_by_label("Transfer detail").click();
    h.run_steps(3);
    let outcome = {
        let app = h.state();
        let job = app.tool.as_ref().expect("detail transfer started");
        assert_eq!(job.name, "detail transfer");
        job.wait().expect("detail transfer succeeded")
    };
    let app = h.state_mut();
    app.tool = None;
    app.state.apply_tool_outcome(outcome);
    assert!(
        app.state.message.contains("strength 2"),
        "{}",
        app.state.message
    );
    let result = (*app.state.slot(Side::Target).unwrap().file).clone();
    // The target was replaced by a refined, displaced copy: the same sphere (mean radius), now
    // with a radial relief far beyond the refinement's own chord sag.
    assert!(result.num_vertices() > target.num_vertices());
    let refined = meshmatch::geometry::refine_to_density(&target, result.num_vertices()).mesh;
    let (s_res, s_flat) = (radial_std(&result), radial_std(&refined));
    let mean_r = result
        .positions
        .iter()
        .map(|p| glam::Vec3::from(*p).length() as f64)
        .sum::<f64>()
        / result.num_vertices() as f64;
    println!(
        "detail from the app: {} vertices, radial std {s_res:.5} (undisplaced refinement {s_flat:.5}, source relief {s_src:.5}), mean radius {mean_r:.4}",
        result.num_vertices()
    );
    assert!((mean_r - 1.0).abs() < 0.01, "mean radius {mean_r}");
    assert!(s_res > 5.0 * s_flat, "relief {s_res} vs {s_flat}");
    // Strength 2 doubles the relief: more than the source's own (strength 1 gives about that).
    assert!(
        s_res > 1.2 * s_src,
        "strength: relief {s_res} vs source {s_src}"
    );
}

/// A sphere with a spherical UV layout (u from the longitude, v from the latitude).
fn mapped_sphere(rings: u32, segments: u32) -> TriMesh {
    let mut m = sphere(rings, segments);
    let uv = |p: [f32; 3]| {
        [
            0.5 + p[2].atan2(p[0]) / (2.0 * std::f32::consts::PI),
            p[1].clamp(-1.0, 1.0).acos() / std::f32::consts::PI,
        ]
    };
    m.uvs = Some(
        m.faces
            .iter()
            .flat_map(|f| f.map(|v| uv(m.positions[v as usize])))
            .collect(),
    );
    m
}

#[test]
fn export_delivers_like_transfer_out_a_baked_texture_in_glb_and_the_dense_mesh_in_ply() {
    use meshmatch::app::engine::MeshMatchEngine;
    let mut app = MeshMatchApp::new(MeshMatchEngine, None);
    app.state.params.vertices = 1500;
    app.state.params.iterations = 1;
    app.state.set_mesh(Side::Source, sphere(12, 16), false);
    app.state
        .set_mesh(Side::Target, mapped_sphere(14, 20), false);
    app.state
        .set_correspondences(vec![Correspondence {
            source_vertex: 0,
            target_vertices: vec![0],
        }])
        .unwrap();
    let t0 = Instant::now();
    loop {
        app.pump(Instant::now());
        let s = &app.state;
        if s.result.is_some() && !s.job.running && !s.restart_pending() {
            break;
        }
        assert!(t0.elapsed() < Duration::from_secs(120), "no result");
        app.wait_events(Duration::from_millis(50));
    }
    let dir = temp_dir("export_delivery");
    let target = app.state.meshes[1].as_ref().unwrap().file.clone();

    let glb = dir.join("result.glb");
    app.state.export_result(&glb).unwrap();
    let m = meshmatch::mesh::io::load(&glb).unwrap();
    let tex = m
        .texture
        .as_ref()
        .expect("a .glb of a target with UVs has a texture");
    let side = meshmatch::app::state::EXPORT_TEXTURE_SIZE;
    assert_eq!(tex.image.dimensions(), (side, side));
    assert!(
        m.colors.is_none(),
        "the texture replaces vertex colours in .glb"
    );
    // The baked texture carries the result's colours, not a blank image.
    let (mut red, mut blue) = (0usize, 0usize);
    for p in tex.image.pixels() {
        red += (p.0[0] > 128 && p.0[2] < 128) as usize;
        blue += (p.0[2] > 128 && p.0[0] < 128) as usize;
    }
    assert!(red > 1000 && blue > 1000, "texture red {red} blue {blue}");

    let ply = dir.join("result.ply");
    app.state.export_result(&ply).unwrap();
    let m = meshmatch::mesh::io::load(&ply).unwrap();
    assert!(m.texture.is_none());
    assert_eq!(m.colors.as_ref().map(Vec::len), Some(target.num_vertices()));

    let dense = dir.join("dense.ply");
    app.state.export_dense_result(&dense).unwrap();
    let m = meshmatch::mesh::io::load(&dense).unwrap();
    let working = app.state.meshes[1]
        .as_ref()
        .unwrap()
        .working
        .clone()
        .unwrap();
    assert_eq!(m.num_vertices(), working.num_vertices());
    assert!(m.num_vertices() > target.num_vertices());
    assert!(m.colors.is_some());

    // From the menu the export runs as a background job (a target without UVs gets an atlas):
    // the window keeps pumping, the status bar says what was written.
    let mut bare = (*target).clone();
    bare.uvs = None;
    bare.texture = None;
    app.state.set_mesh(Side::Target, bare, false);
    let t0 = Instant::now();
    loop {
        app.pump(Instant::now());
        let s = &app.state;
        if s.result.is_some() && !s.job.running && !s.restart_pending() {
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(120),
            "no result on the bare target"
        );
        app.wait_events(Duration::from_millis(50));
    }
    let atlas_glb = dir.join("atlas.glb");
    app.start_export(&atlas_glb);
    let t0 = Instant::now();
    while app.tool.is_some() {
        app.poll_tool();
        assert!(
            t0.elapsed() < Duration::from_secs(120),
            "export never finished"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(
        app.state.message.contains("exported") && app.state.message.contains("charts"),
        "{}",
        app.state.message
    );
    let m = meshmatch::mesh::io::load(&atlas_glb).unwrap();
    assert!(m.uvs.is_some() && m.texture.is_some());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn cancel_during_preparation_stops_inside_the_hierarchy_build() {
    use meshmatch::meshmatch::{TransferParams, prepare};
    let mesh = sphere(40, 64);
    let params = TransferParams {
        vertices: 256_000,
        ..TransferParams::default()
    };
    let cancel = CancelToken::new();
    let events = std::sync::Mutex::new(Vec::new());
    let sink = |e: Event| match e {
        Event::Progress(p) => {
            if p.stage == "hierarchy" {
                // Asked from another thread, as the UI does; joined so the stop is set before
                // the hierarchy build starts.
                let c = cancel.clone();
                std::thread::spawn(move || c.cancel()).join().unwrap();
            }
            events.lock().unwrap().push(p.stage.to_string());
        }
        Event::StageTime(name, _) => events.lock().unwrap().push(format!("time {name}")),
        Event::Partial { .. } => {}
    };
    let r = prepare(&mesh, &params, &sink, &cancel);
    assert!(
        matches!(r, Err(meshmatch::Error::Cancelled)),
        "prepare was not cancelled"
    );
    let events = events.into_inner().unwrap();
    assert!(events.contains(&"time refine".to_string()), "{events:?}");
    // The hierarchy was abandoned, not built to the end and then cancelled.
    assert!(
        !events.contains(&"time hierarchy".to_string()),
        "{events:?}"
    );
}

#[test]
fn brush_cursor_is_the_dab_disc_or_lies_on_the_surface_painting_through() {
    let mut app = app_with_spheres();
    app.views.tool = meshmatch::app::Tool::Paint;
    app.state.brush.radius = 0.05;
    let mut h = harness(app);
    h.step();
    let side = Side::Target;
    let ratio = |pts: &[Pos2]| {
        let n = pts.len() as f32;
        let c = pts.iter().fold(egui::Vec2::ZERO, |a, p| a + p.to_vec2()) / n;
        let d: Vec<f32> = pts.iter().map(|p| (p.to_vec2() - c).length()).collect();
        let max = d.iter().cloned().fold(0.0f32, f32::max);
        let min = d.iter().cloned().fold(f32::INFINITY, f32::min);
        (max / min, c.to_pos2(), min)
    };
    let front = vertex_pos(&h, side, front_vertex(&h, side, 0));
    let app = h.state();
    let rect = app.views.rects[1];
    // Off the mesh: no cursor.
    let corner = rect.min + egui::Vec2::new(4.0, rect.height() - 4.0);
    assert!(app.views.pick_at(&app.state, side, rect, corner).is_none());
    assert!(
        app.views
            .brush_outline(&app.state, side, rect, corner)
            .is_none()
    );
    // A dab from the view: the disc it paints, a circle around the pointer of the brush's
    // radius on the screen at the picked point, facing the camera or not.
    let mut edge = front;
    while app
        .views
        .pick_at(&app.state, side, rect, edge + egui::Vec2::X)
        .is_some()
    {
        edge += egui::Vec2::X;
    }
    let oblique = front + 0.9 * (edge - front);
    for pos in [front, oblique] {
        let pts = app
            .views
            .brush_outline(&app.state, side, rect, pos)
            .expect("cursor on the mesh");
        let (r, c, radius) = ratio(&pts);
        assert!(r < 1.01, "disc outline ratio {r}");
        assert!(
            c.distance(pos) < 0.5,
            "outline centre {c:?} pointer {pos:?}"
        );
        let view = app.views.brush_view(&app.state, side, rect, pos).unwrap();
        let frame = meshmatch::render::Frame::of_points(
            &app.state.slot(side).unwrap().displayed().positions,
        );
        let expect = view.screen_radius(0.05 * frame.radius);
        assert!(
            (radius - expect).abs() < 0.02 * expect + 0.5,
            "outline radius {radius}, dab radius {expect}"
        );
    }
    // Painting through: the ball's circle in the tangent plane, a near-circle facing the
    // camera, a flat ellipse where the surface is seen edge-on.
    h.state_mut().state.brush.through = true;
    let app = h.state();
    let pts = app
        .views
        .brush_outline(&app.state, side, rect, front)
        .expect("cursor on the mesh");
    assert_eq!(pts.len(), 32);
    let (r, c, _) = ratio(&pts);
    assert!(r < 1.3, "front outline ratio {r}");
    assert!(
        c.distance(front) < 3.0,
        "outline centre {c:?} pointer {front:?}"
    );
    let pts = app
        .views
        .brush_outline(&app.state, side, rect, oblique)
        .expect("cursor on the mesh");
    let (r, _, _) = ratio(&pts);
    assert!(r > 1.5, "oblique outline ratio {r}");
}

/// The app with real GPU viewports (lavapipe where there is no GPU): the views draw into
/// textures that `Harness::render` shows.
fn gpu_harness(app: App) -> Harness<'static, App> {
    use egui_kittest::wgpu::{WgpuTestRenderer, create_render_state, default_wgpu_setup};
    let rs = create_render_state(
        default_wgpu_setup(),
        eframe::egui_wgpu::RendererOptions::PREDICTABLE,
    );
    let ui_rs = rs.clone();
    Harness::builder()
        .with_size(egui::Vec2::new(1200.0, 700.0))
        .with_max_steps(20)
        .renderer(WgpuTestRenderer::from_render_state(rs))
        .build_ui_state(move |ui, app: &mut App| app.frame_ui(ui, Some(&ui_rs)), app)
}

#[test]
fn markers_are_spheres_in_the_views_that_the_mesh_hides() {
    // Grey spheres (the test engine copies source colours, so the target stays grey too).
    let grey = |mut m: TriMesh| {
        m.colors = Some(vec![[0.6, 0.6, 0.6]; m.positions.len()]);
        m
    };
    let mut app = App::new(TestEngine::default(), None);
    app.state
        .set_mesh(Side::Source, grey(sphere(12, 16)), false);
    app.state
        .set_mesh(Side::Target, grey(sphere(16, 24)), false);
    let mut h = gpu_harness(app);
    h.run_steps(3);
    // A pair added by clicks (picking through the views' BVH).
    let s0 = front_vertex(&h, Side::Source, 0);
    let t0 = front_vertex(&h, Side::Target, 0);
    click_vertex(&mut h, Side::Source, s0, egui::Modifiers::NONE);
    click_vertex(&mut h, Side::Target, t0, egui::Modifiers::NONE);
    assert_eq!(
        h.state().state.corr,
        vec![Correspondence {
            source_vertex: s0,
            target_vertices: vec![t0]
        }]
    );
    h.state_mut().state.select(None);
    h.run_steps(2);
    let [r, g, b] = meshmatch::render::marker_color(0).map(i32::from);
    assert!(r > g + 100 && r > b + 100, "pair 1 is red: {r} {g} {b}");
    // Red minus green at a point on the sphere beside its number (the label sits on the centre).
    let redness = |h: &mut Harness<'static, App>, side: Side, v: u32| {
        let p = vertex_pos(h, side, v) + egui::vec2(-5.0, -3.0);
        let img = h.render().expect("render");
        let ppp = h.ctx.pixels_per_point();
        let px = img.get_pixel((p.x * ppp) as u32, (p.y * ppp) as u32);
        px[0] as i32 - px[1] as i32
    };
    let mut front = Vec::new();
    for (side, v) in [(Side::Source, s0), (Side::Target, t0)] {
        let f = redness(&mut h, side, v);
        assert!(f > 100, "{side:?} marker in view: red - green = {f}");
        front.push(f);
    }
    // Turn both (locked) cameras around: the markers are now behind the spheres, which hide them
    // but for a faint tint.
    for c in &mut h.state_mut().views.cameras {
        c.azimuth_deg += 180.0;
    }
    h.state_mut().views.invalidate();
    h.run_steps(2);
    // The hidden part is drawn at 30% opacity in linear light, which sRGB encoding lifts to about
    // half the in-view tint; a marker the mesh did not hide would give the full tint.
    for ((side, v), f) in [(Side::Source, s0), (Side::Target, t0)]
        .into_iter()
        .zip(front)
    {
        let behind = redness(&mut h, side, v);
        eprintln!("{side:?}: red - green in view {f}, behind the mesh {behind}");
        assert!(
            behind > 5 && 3 * behind < 2 * f,
            "{side:?} marker behind the mesh: red - green = {behind} (in view {f})"
        );
    }
}

#[test]
fn file_open_works_without_a_system_dialog_through_the_built_in_browser() {
    let dir = Scratch::new("browser");
    let sub = dir.join("meshes");
    std::fs::create_dir_all(&sub).unwrap();
    let mesh = sub.join("ball.ply");
    meshmatch::mesh::io::save(&sphere(6, 8), &mesh).unwrap();
    std::fs::write(sub.join("notes.txt"), "not a mesh").unwrap();
    let mut app = app_with_spheres();
    // As on a machine without a desktop portal (a bare Xvfb).
    app.files.native = false;
    let mut h = harness(app);
    h.run_steps(2);
    h.get_by_label("File").click();
    h.run_steps(2);
    h.get_by_label("Open target mesh...").click();
    h.run_steps(3);
    assert!(h.state().files.browsing(), "the built-in browser opened");
    // Type the folder, then pick the mesh from the listing (the text file is not offered).
    let folder = h
        .get_all_by_role(egui::accesskit::Role::TextInput)
        .next()
        .unwrap();
    folder.focus();
    h.run_steps(1);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    h.run_steps(1);
    h.get_all_by_role(egui::accesskit::Role::TextInput)
        .next()
        .unwrap()
        .type_text(&format!("{}", sub.display()));
    h.run_steps(1);
    h.key_press(egui::Key::Enter);
    h.run_steps(3);
    assert!(h.query_by_label("notes.txt").is_none());
    h.get_by_label("ball.ply").click();
    h.run_steps(2);
    h.get_by_label("Open").click();
    h.run_steps(3);
    assert!(!h.state().files.browsing());
    let target = h.state().state.slot(Side::Target).unwrap();
    assert_eq!(target.file.path.as_deref(), Some(mesh.as_path()));
    assert_eq!(target.file.positions.len(), sphere(6, 8).positions.len());
    std::fs::remove_dir_all(&dir).ok();
}

/// A sphere with radial bumps `1 + a sin(k theta) sin(k phi)`: crevices between the bumps.
fn bumpy_sphere(rings: u32, segments: u32, k: f32, a: f32) -> TriMesh {
    let mut m = sphere(rings, segments);
    for p in &mut m.positions {
        let v = glam::Vec3::from(*p);
        let theta = v.y.clamp(-1.0, 1.0).acos();
        let phi = v.z.atan2(v.x);
        let r = 1.0 + a * (k * theta).sin() * (k * phi).sin();
        *p = (v * r).to_array();
    }
    m.colors = None;
    m
}

fn wait_tool(h: &mut Harness<'static, App>, limit: Duration) {
    let t0 = Instant::now();
    while h.state().tool.is_some() {
        h.step();
        assert!(t0.elapsed() < limit, "the tool did not finish");
        std::thread::sleep(Duration::from_millis(10));
    }
    h.run_steps(2);
}

fn target_vertices(h: &Harness<'static, App>) -> usize {
    h.state()
        .state
        .slot(Side::Target)
        .unwrap()
        .file
        .num_vertices()
}

fn system_index<T: 'static>(h: &mut Harness<'static, App>) -> usize {
    let app = h.state_mut();
    (0..app.systems.len())
        .find(|&i| {
            let any: &mut dyn std::any::Any = app.systems[i].as_any_mut();
            any.is::<T>()
        })
        .expect("registered")
}

#[test]
fn weather_tool_learns_dark_crevices_from_the_source_and_one_undo_restores() {
    use meshmatch::app::weathering::WeatherDialog;
    use meshmatch::synthesis::weathering::{self, Params};
    // The source's colour is its own ambient occlusion: dark in the crevices between bumps.
    let mut source = bumpy_sphere(40, 64, 5.0, 0.18);
    let params = Params {
        rays: 48,
        ..Params::default()
    };
    let ao = |m: &TriMesh| {
        let fs =
            weathering::features(&m.positions, &m.faces, &params, &CancelToken::new()).unwrap();
        weathering::feature_field(&fs, "ao").unwrap()
    };
    source.colors = Some(ao(&source).iter().map(|&a| [a, a * 0.9, a * 0.8]).collect());
    let target = bumpy_sphere(48, 72, 7.0, 0.14);
    let mut app = App::new(TestEngine::default(), None);
    app.state.set_mesh(Side::Source, source, false);
    app.state.set_mesh(Side::Target, target, false);
    let mut h = harness(app);
    // Let the worker prepare the target: the view then shows its working mesh.
    let t0 = Instant::now();
    while h
        .state()
        .state
        .slot(Side::Target)
        .unwrap()
        .working
        .is_none()
    {
        h.step();
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "target not prepared"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    // And let the transfer the two meshes started settle: its result sets the target's colours,
    // which the weathering step's undo rightly does not take back.
    while h.state().state.job.running || h.state().state.restart_pending() {
        h.step();
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "transfer did not settle"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    h.run_steps(2);
    let before = h.state().state.slot(Side::Target).unwrap().display_colors();
    let i = system_index::<WeatherDialog>(&mut h);
    {
        let d = h.state_mut().system_mut::<WeatherDialog>().unwrap();
        d.settings.vertices = 6_000;
        d.settings.rays = 32;
        d.settings.clusters = 12;
    }
    h.state_mut().start_system(i);
    assert!(h.state().tool.is_some(), "{:?}", h.state().state.errors);
    wait_tool(&mut h, Duration::from_secs(120));
    let st = &h.state().state;
    assert!(st.errors.is_empty(), "{:?}", st.errors);
    let slot = st.slot(Side::Target).unwrap();
    let after = slot.display_colors();
    let truth = ao(slot.displayed());
    let lum: Vec<f32> = after.iter().map(|c| (c[0] + c[1] + c[2]) / 3.0).collect();
    let r = meshmatch::stats::pearson(&lum, &truth) as f32;
    println!("weather: correlation of the target's lightness with its own AO: {r:.3}");
    assert!(r > 0.6, "correlation {r}");
    assert!(
        st.message.contains("features that matter"),
        "{}",
        st.message
    );
    assert_eq!(st.history_len().0, 1);
    h.state_mut().state.undo();
    let undone = h.state().state.slot(Side::Target).unwrap().display_colors();
    assert!(undone == before, "undo did not restore the colours");
}

#[test]
fn quilt_tool_covers_the_target_with_whole_elements_and_one_undo_brings_it_back() {
    use meshmatch::app::quilting::QuiltDialog;
    let mut app = App::new(TestEngine::default(), None);
    app.state.set_mesh(Side::Source, sphere(12, 16), false);
    app.state.set_mesh(Side::Target, sphere(24, 32), false);
    let mut h = harness(app);
    h.run_steps(2);
    let n_before = target_vertices(&h);
    let i = system_index::<QuiltDialog>(&mut h);
    h.state_mut().system_mut::<QuiltDialog>().unwrap().size = 0.25;
    h.state_mut().start_system(i);
    wait_tool(&mut h, Duration::from_secs(120));
    let st = &h.state().state;
    assert!(st.errors.is_empty(), "{:?}", st.errors);
    assert!(st.message.contains("quilted"), "{}", st.message);
    let quilted = st.slot(Side::Target).unwrap().file.clone();
    let components = meshmatch::mesh::connected_components(quilted.num_vertices(), &quilted.faces);
    println!(
        "quilt: {} vertices, {} components",
        quilted.num_vertices(),
        components.1
    );
    // The base and at least a few dozen whole elements.
    assert!(components.1 > 20, "{} components", components.1);
    h.state_mut().state.undo();
    assert_eq!(target_vertices(&h), n_before);
    // the weave with "merge threads across seams" ticked: threads join, still one undo step
    {
        let d = h.state_mut().system_mut::<QuiltDialog>().unwrap();
        d.swatch = meshmatch::app::quilting::SwatchChoice::Builtin(
            meshmatch::synthesis::quilting::SwatchKind::Weave,
        );
        d.merge = true;
    }
    h.state_mut().start_system(i);
    wait_tool(&mut h, Duration::from_secs(120));
    let st = &h.state().state;
    assert!(st.errors.is_empty(), "{:?}", st.errors);
    assert!(st.message.contains("merged across seams"), "{}", st.message);
    h.state_mut().state.undo();
    assert_eq!(target_vertices(&h), n_before);
}

/// A cube of side 2 with an `n x n` grid on each face (sharp creases along its 12 edges).
fn grid_cube(n: i32) -> TriMesh {
    let mut index = std::collections::HashMap::new();
    let mut pos: Vec<[f32; 3]> = Vec::new();
    let mut faces = Vec::new();
    let mut id = |k: [i32; 3], pos: &mut Vec<[f32; 3]>| -> u32 {
        *index.entry(k).or_insert_with(|| {
            pos.push(k.map(|x| x as f32 * 2.0 / n as f32 - 1.0));
            pos.len() as u32 - 1
        })
    };
    for a in 0..3 {
        for side in [0, n] {
            let (b, c) = ((a + 1) % 3, (a + 2) % 3);
            for i in 0..n {
                for j in 0..n {
                    let key = |di: i32, dj: i32| {
                        let mut k = [0; 3];
                        k[a] = side;
                        k[b] = i + di;
                        k[c] = j + dj;
                        k
                    };
                    let q = [key(0, 0), key(1, 0), key(1, 1), key(0, 1)].map(|k| id(k, &mut pos));
                    let (t1, t2) = ([q[0], q[1], q[2]], [q[0], q[2], q[3]]);
                    if side == n {
                        faces.extend([t1, t2]);
                    } else {
                        faces.extend([[t1[0], t1[2], t1[1]], [t2[0], t2[2], t2[1]]]);
                    }
                }
            }
        }
    }
    TriMesh::new(pos, faces)
}

/// Wait until the target is prepared and any transfer the meshes started has finished (its
/// result would change the target's colours underneath a tool and its undo).
fn settle_target(h: &mut Harness<'static, App>) {
    let t0 = Instant::now();
    while h
        .state()
        .state
        .slot(Side::Target)
        .unwrap()
        .working
        .is_none()
    {
        h.step();
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "target not prepared"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    // Let any transfer the meshes started finish first: its result would change the target's
    // colours underneath the tool and the undo (a race on a loaded machine).
    let t0 = Instant::now();
    loop {
        let st = &h.state().state;
        let settled = st.job.outcome.starts_with("done")
            || st.job.outcome.starts_with("failed")
            || st.job.outcome == "cancelled";
        if settled && !st.job.running && !st.restart_pending() {
            break;
        }
        h.step();
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "transfer never settled"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// The app with a sphere as source and the demo block (a cube and a cylinder: 14 creases and
/// rims) as target, prepared and settled.
fn block_harness() -> Harness<'static, App> {
    let mut app = App::new(TestEngine::default(), None);
    app.state.set_mesh(Side::Source, sphere(12, 16), false);
    app.state
        .set_mesh(Side::Target, meshmatch::demo::crest_block(10), false);
    let mut h = harness(app);
    settle_target(&mut h);
    h
}

#[test]
fn feature_aligned_tool_shows_the_found_curves_and_uses_only_the_kept_ones() {
    use meshmatch::app::feature_aligned::FeatureAlignedDialog;
    let dir = temp_dir("feature_aligned_curves");
    let image = dir.join("line.png");
    meshmatch::demo::line_exemplar().save(&image).unwrap();
    let mut h = block_harness();
    let i = system_index::<FeatureAlignedDialog>(&mut h);
    {
        let d = h.state_mut().system_mut::<FeatureAlignedDialog>().unwrap();
        d.open = true;
        d.image = Some(image);
        d.scale = 0.3;
        d.pixels = 32;
    }
    h.run_steps(2);
    h.get_by_label("Find curves").click();
    h.run_steps(3);
    let found = {
        let d = h.state_mut().system_mut::<FeatureAlignedDialog>().unwrap();
        d.found.clone().expect("curves found")
    };
    // a cube's 12 creases and a cylinder's two rims
    assert_eq!(found.curves.len(), 14, "{:?}", h.state().state.errors);
    assert!(h.state().state.overlay.is_some(), "the curves are drawn");
    // orange strokes in the target view
    let img = h.render().expect("render");
    let orange = img
        .pixels()
        .filter(|p| p[0] > 220 && p[1] > 110 && p[1] < 190 && p[2] < 80)
        .count();
    if let Ok(dir) = std::env::var("MESHMATCH_SHOT_DIR") {
        img.save(std::path::Path::new(&dir).join("feature_aligned_curves.png"))
            .unwrap();
    }
    assert!(orange > 200, "{orange} orange pixels");
    // keep only the longest curve and run: the message names one curve
    {
        let d = h.state_mut().system_mut::<FeatureAlignedDialog>().unwrap();
        let f = d.found.as_mut().unwrap();
        for k in f.kept.iter_mut().skip(1) {
            *k = false;
        }
    }
    h.state_mut().start_system(i);
    assert!(h.state().tool.is_some(), "{:?}", h.state().state.errors);
    wait_tool(&mut h, Duration::from_secs(120));
    let st = &h.state().state;
    assert!(st.errors.is_empty(), "{:?}", st.errors);
    assert!(
        st.message.contains("along 1 salient curves"),
        "{}",
        st.message
    );
    // dropping every curve is refused in one line
    {
        let d = h.state_mut().system_mut::<FeatureAlignedDialog>().unwrap();
        d.found
            .as_mut()
            .unwrap()
            .kept
            .iter_mut()
            .for_each(|k| *k = false);
    }
    h.state_mut().start_system(i);
    assert!(h.state().tool.is_none());
    let errors = &h.state().state.errors;
    assert!(
        errors
            .last()
            .is_some_and(|e| e.contains("every curve is dropped")),
        "{errors:?}"
    );
}

#[test]
fn feature_aligned_tool_draws_the_field_and_a_click_on_a_curve_drops_it() {
    use meshmatch::app::feature_aligned::FeatureAlignedDialog;
    let mut h = block_harness();
    h.state_mut()
        .system_mut::<FeatureAlignedDialog>()
        .unwrap()
        .open = true;
    h.run_steps(2);
    h.get_by_label("Find curves").click();
    h.run_steps(3);
    h.get_by_label("Show the field").click();
    // the field arrives from its own thread
    let wait_field = |h: &mut Harness<'static, App>| {
        let t0 = Instant::now();
        loop {
            h.step();
            let d = h.state_mut().system_mut::<FeatureAlignedDialog>().unwrap();
            let kept = d.found.as_ref().unwrap().kept.clone();
            if d.field.as_ref().is_some_and(|f| f.kept == kept) && !d.field_running() {
                return d.field.clone().unwrap();
            }
            assert!(t0.elapsed() < Duration::from_secs(60), "no field");
            std::thread::sleep(Duration::from_millis(20));
        }
    };
    let field = wait_field(&mut h);
    let found = h
        .state_mut()
        .system_mut::<FeatureAlignedDialog>()
        .unwrap()
        .found
        .clone()
        .unwrap();
    assert!(field.arrows.len() > 100, "{} arrows", field.arrows.len());
    // next to a crease, the arrows run along it
    let mut checked = 0;
    let mut worst: f32 = 1.0;
    let block = meshmatch::demo::crest_block(10);
    let h_edge = meshmatch::geometry::mean_edge_length(&block.positions, &block.faces);
    for c in found.curves.iter().filter(|c| !c.closed) {
        // away from the corners, where three creases meet and the field is released
        let n = c.points.len();
        for w in c.points[2.min(n)..n.saturating_sub(2).max(2.min(n))].windows(2) {
            let (a, b) = (glam::Vec3::from(w[0]), glam::Vec3::from(w[1]));
            let mid = (a + b) * 0.5;
            let t = (b - a).normalize();
            for [s, e] in field.arrows.iter() {
                let (s, e) = (glam::Vec3::from(*s), glam::Vec3::from(*e));
                if ((s + e) * 0.5).distance(mid) < 0.5 * h_edge {
                    worst = worst.min((e - s).normalize().dot(t).abs());
                    checked += 1;
                }
            }
        }
    }
    assert!(checked >= 10, "{checked} arrows on creases");
    assert!(
        worst > 0.9,
        "an arrow on a crease crosses it: |cos| {worst}"
    );
    h.run_steps(2);
    let img = h.render().expect("render");
    let cyan = img
        .pixels()
        .filter(|p| p[2] as i32 > p[0] as i32 + 60 && p[1] as i32 > p[0] as i32 + 50)
        .count();
    if let Ok(dir) = std::env::var("MESHMATCH_SHOT_DIR") {
        img.save(std::path::Path::new(&dir).join("feature_aligned_field.png"))
            .unwrap();
    }
    assert!(cyan > 200, "{cyan} cyan pixels");
    // click the middle of a curve in sight, outside any window: it is dropped, the field follows
    let pick = {
        let app = h.state();
        found.curves.iter().enumerate().find_map(|(k, c)| {
            let mid = c.points[c.points.len() / 2];
            let (pos, hidden) = app.views.project_point(&app.state, Side::Target, mid)?;
            let free = h
                .ctx
                .layer_id_at(pos)
                .is_none_or(|l| l.order == egui::Order::Background);
            (!hidden && free && app.views.rects[1].shrink(10.0).contains(pos)).then_some((k, pos))
        })
    };
    let (k, pos) = pick.expect("a curve in sight");
    click(&mut h, pos, egui::Modifiers::NONE);
    let kept = |h: &mut Harness<'static, App>| {
        h.state_mut()
            .system_mut::<FeatureAlignedDialog>()
            .unwrap()
            .found
            .as_ref()
            .unwrap()
            .kept
            .clone()
    };
    let after = kept(&mut h);
    assert!(!after[k], "curve {k} still kept after a click on it");
    assert_eq!(after.iter().filter(|x| !**x).count(), 1, "{after:?}");
    assert!(
        h.state().state.corr.is_empty() && h.state().state.selected.is_none(),
        "the click also acted on the correspondences"
    );
    let refreshed = wait_field(&mut h);
    assert_eq!(refreshed.kept, after);
    // a second click keeps it again
    click(&mut h, pos, egui::Modifiers::NONE);
    assert!(kept(&mut h)[k]);
}

#[test]
fn feature_aligned_tool_textures_a_cube_along_its_creases_and_one_undo_restores() {
    use meshmatch::app::feature_aligned::FeatureAlignedDialog;
    // Horizontal stripes: the exemplar's x axis (its lines) should follow the cube's edges.
    let dir = temp_dir("feature_aligned_tool");
    let image = dir.join("stripes.png");
    image::RgbImage::from_fn(64, 64, |_, y| {
        if (y / 8) % 2 == 0 {
            image::Rgb([20, 20, 20])
        } else {
            image::Rgb([230, 230, 230])
        }
    })
    .save(&image)
    .unwrap();
    let mut app = App::new(TestEngine::default(), None);
    app.state.set_mesh(Side::Source, sphere(12, 16), false);
    app.state.set_mesh(Side::Target, grid_cube(16), false);
    let mut h = harness(app);
    settle_target(&mut h);
    h.run_steps(2);
    let before = h.state().state.slot(Side::Target).unwrap().display_colors();
    let i = system_index::<FeatureAlignedDialog>(&mut h);
    {
        let d = h.state_mut().system_mut::<FeatureAlignedDialog>().unwrap();
        d.image = Some(image);
        d.scale = 0.3;
        d.pixels = 32;
    }
    h.state_mut().start_system(i);
    assert!(h.state().tool.is_some(), "{:?}", h.state().state.errors);
    wait_tool(&mut h, Duration::from_secs(120));
    let st = &h.state().state;
    assert!(st.errors.is_empty(), "{:?}", st.errors);
    assert!(st.message.contains("salient curves"), "{}", st.message);
    let after = st.slot(Side::Target).unwrap().display_colors();
    let lum = |c: &[f32; 3]| (c[0] + c[1] + c[2]) / 3.0;
    let dark = after.iter().filter(|c| lum(c) < 0.3).count();
    let light = after.iter().filter(|c| lum(c) > 0.7).count();
    println!(
        "feature-aligned: {dark} dark and {light} light of {} vertices; {}",
        after.len(),
        st.message
    );
    // The stripes' two tones, both well represented.
    assert!(dark * 5 > after.len() && light * 5 > after.len());
    h.state_mut().state.undo();
    let undone = h.state().state.slot(Side::Target).unwrap().display_colors();
    assert!(undone == before, "undo did not restore the colours");
}

#[test]
fn suggest_adds_well_spread_pairs_from_the_map_and_one_undo_removes_them() {
    let load = |n: &str| meshmatch::mesh::io::load(&meshmatch::testdata::data_path(n)).unwrap();
    let man = load("human/human_man.obj");
    let mut app = App::new(TestEngine::default(), None);
    app.state.set_mesh(Side::Source, man.clone(), false);
    app.state
        .set_mesh(Side::Target, load("human/human_woman.obj"), false);
    // head top and one hand, as a user would click them (SMPL: same vertex ids on both)
    for v in [411u32, 2445] {
        app.state.corr.push(Correspondence {
            source_vertex: v,
            target_vertices: vec![v],
        });
    }
    let mut h = harness(app);
    h.run_steps(2);
    h.get_by_label("Suggest").click();
    h.run_steps(2);
    assert!(h.state().tool.is_some(), "suggest started");
    wait_tool(&mut h, Duration::from_secs(120));
    let corr = h.state().state.corr.clone();
    assert_eq!(
        corr.len(),
        2 + meshmatch::app::tools::SUGGESTED_PAIRS,
        "{}",
        h.state().state.message
    );
    // Each suggestion pairs a woman vertex with the man's vertex at the same place: the truth is
    // the same vertex id.
    let tol = 0.1 * man.area().sqrt() as f32;
    let d = |a: [f32; 3], b: [f32; 3]| (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f32>().sqrt();
    let mut targets = Vec::new();
    for c in &corr[2..] {
        let t = c.target_vertices[0];
        let e = d(
            man.positions[c.source_vertex as usize],
            man.positions[t as usize],
        );
        assert!(
            e < tol,
            "pair {} -> {t}: {e} from the truth",
            c.source_vertex
        );
        targets.push(man.positions[t as usize]);
    }
    // well spread: no two suggested target markers closer than a tenth of the body's size
    for i in 0..targets.len() {
        for j in 0..i {
            assert!(
                d(targets[i], targets[j]) > 0.17,
                "markers {i} and {j} bunch up"
            );
        }
    }
    // one undo step removes all of them
    h.state_mut().state.undo();
    assert_eq!(h.state().state.corr.len(), 2);
}

#[test]
fn a_textured_source_is_drawn_through_its_texture_before_and_after_preparation() {
    use meshmatch::app::engine::MeshMatchEngine;
    let spot = meshmatch::mesh::io::load(&meshmatch::testdata::data_path("spot/spot.obj")).unwrap();
    let mut app = MeshMatchApp::new(MeshMatchEngine, None);
    app.state.params.vertices = 8000;
    app.state.set_mesh(Side::Source, spot, false);
    assert!(app.state.slot(Side::Source).unwrap().shows_texture());
    app.state.set_mesh(Side::Target, sphere(12, 16), false);
    app.state
        .set_correspondences(vec![Correspondence {
            source_vertex: 0,
            target_vertices: vec![0],
        }])
        .unwrap();
    // Once the working mesh is prepared it carries the texture and UVs at every working corner.
    let t0 = Instant::now();
    while app.state.slot(Side::Source).unwrap().working.is_none() {
        app.pump(Instant::now());
        assert!(t0.elapsed() < Duration::from_secs(120), "never prepared");
        app.wait_events(Duration::from_millis(50));
    }
    let slot = app.state.slot(Side::Source).unwrap();
    let w = slot.working.as_ref().unwrap();
    assert!(w.num_vertices() > slot.file.num_vertices());
    assert_eq!(w.uvs.as_ref().map(Vec::len), Some(3 * w.num_faces()));
    assert!(slot.shows_texture());
    // The working UVs put every working vertex on the texture where the file mesh has it: the
    // texture sampled at the working corners agrees with the working colours (sampled from the
    // same texture at preparation).
    let tex = &w.texture.as_ref().unwrap().image;
    let uvs = w.uvs.as_ref().unwrap();
    let cols = w.colors.as_ref().unwrap();
    let mut far = 0;
    for (f, face) in w.faces.iter().enumerate().step_by(7) {
        let uv = uvs[3 * f];
        let (x, y) = (
            ((uv[0] * tex.width() as f32) as u32).min(tex.width() - 1),
            (((1.0 - uv[1]) * tex.height() as f32) as u32).min(tex.height() - 1),
        );
        let t = tex.get_pixel(x, y).0.map(|c| c as f32 / 255.0);
        let c = cols[face[0] as usize];
        if (0..3).any(|k| (t[k] - c[k]).abs() > 0.25) {
            far += 1;
        }
    }
    assert!(
        far * 20 < w.num_faces() / 7,
        "{far} corners disagree with the texture"
    );
}

#[test]
fn view_menu_opens_the_geometric_feature_window() {
    use meshmatch::app::weathering::FeatureDialog;
    let mut h = harness(app_with_spheres());
    h.run_steps(2);
    assert!(!h.state().system::<FeatureDialog>().unwrap().open);
    h.get_by_label("View").click();
    h.run_steps(2);
    h.get_by_label("Show geometric feature...").click();
    h.run_steps(2);
    assert!(h.state().system::<FeatureDialog>().unwrap().open);
}

#[test]
fn the_weather_window_runs_again_without_a_switched_off_component() {
    use meshmatch::app::weathering::WeatherDialog;
    let mut source = bumpy_sphere(24, 36, 5.0, 0.18);
    source.colors = Some(
        source
            .positions
            .iter()
            .map(|p| {
                let t = 0.5 + 0.5 * p[1];
                [t, 0.6 * t, 0.3]
            })
            .collect(),
    );
    let mut app = App::new(TestEngine::default(), None);
    app.state.set_mesh(Side::Source, source, false);
    app.state
        .set_mesh(Side::Target, bumpy_sphere(24, 36, 7.0, 0.14), false);
    let mut h = harness(app);
    h.run_steps(2);
    let i = system_index::<WeatherDialog>(&mut h);
    {
        let d = h.state_mut().system_mut::<WeatherDialog>().unwrap();
        d.open = true;
        d.settings.vertices = 4_000;
        d.settings.rays = 16;
        d.settings.clusters = 8;
        d.settings.components = [true, false, true];
        assert_eq!(d.settings.component_list(), Some(vec![0, 2]));
    }
    h.state_mut().start_system(i);
    assert!(h.state().tool.is_some(), "{:?}", h.state().state.errors);
    wait_tool(&mut h, Duration::from_secs(120));
    assert!(
        h.state().state.errors.is_empty(),
        "{:?}",
        h.state().state.errors
    );
    let report = {
        let d = h.state_mut().system_mut::<WeatherDialog>().unwrap();
        d.report.lock().unwrap().clone().expect("a report")
    };
    assert_eq!(report.enabled, vec![true, false, true]);
    assert!(report.to_text().contains("off"), "{}", report.to_text());
    // the window lists every component with its switch
    h.state_mut().system_mut::<WeatherDialog>().unwrap().open = true;
    h.run_steps(3);
    assert!(
        h.query_by_label_contains("component 1: correlation")
            .is_some(),
        "the window does not list the components"
    );
}

#[test]
fn the_feature_window_saves_every_map_through_the_meshs_uvs() {
    use meshmatch::app::weathering::FeatureDialog;
    let spot_path = meshmatch::testdata::data_path("spot/spot.obj");
    let mut app = App::new(TestEngine::default(), None);
    app.state.set_mesh(Side::Source, sphere(12, 16), false);
    app.state.open_mesh(Side::Target, &spot_path).unwrap();
    let mut h = harness(app);
    h.run_steps(2);
    let scratch = Scratch::new("feature_maps");
    let out = scratch.join("spot.png");
    let i = system_index::<FeatureDialog>(&mut h);
    {
        let d = h.state_mut().system_mut::<FeatureDialog>().unwrap();
        d.side = Side::Target;
        d.rays = 16;
        d.texture_size = 256;
        d.bits = 16;
        d.save_to = Some(out.clone());
    }
    h.state_mut().start_system(i);
    assert!(h.state().tool.is_some(), "{:?}", h.state().state.errors);
    wait_tool(&mut h, Duration::from_secs(120));
    let st = &h.state().state;
    assert!(st.errors.is_empty(), "{:?}", st.errors);
    assert!(st.message.contains("wrote 6 maps"), "{}", st.message);
    assert!(
        !st.message.contains("atlas"),
        "spot has UVs: {}",
        st.message
    );
    for name in ["ao", "curvature", "cavity", "thickness", "normal", "height"] {
        let img = image::open(scratch.join(format!("spot_{name}.png"))).unwrap();
        assert_eq!((img.width(), img.height()), (256, 256), "{name}");
        assert!(
            matches!(img.color(), image::ColorType::L16 | image::ColorType::Rgb16),
            "{name}: {:?}",
            img.color()
        );
    }
    // the next run shows a feature again, it does not save
    assert!(
        h.state()
            .system::<FeatureDialog>()
            .unwrap()
            .save_to
            .is_none()
    );
}

#[test]
fn paint_with_exemplar_into_a_texture_textures_the_mesh_through_its_uvs_and_undo_restores() {
    use meshmatch::app::tools::{ExemplarSettings, Region, TEXTURE_SIDE};
    let spot_path = meshmatch::testdata::data_path("spot/spot.obj");
    let mut app = App::new(TestEngine::default(), None);
    app.state.set_mesh(Side::Source, sphere(12, 16), false);
    app.state.open_mesh(Side::Target, &spot_path).unwrap();
    let before = app.state.slot(Side::Target).unwrap().displayed().clone();
    let own = before.texture.clone().expect("Spot is textured");
    // A small green speckle exemplar: few texels, a short run.
    let scratch = Scratch::new("tex_ex");
    let ex = scratch.join("ex.png");
    image::RgbImage::from_fn(48, 48, |x, y| {
        let h = ((x * 73 + y * 151) % 29) as u8;
        image::Rgb([20 + h, 150 + h, 30 + h])
    })
    .save(&ex)
    .unwrap();
    let settings = ExemplarSettings {
        image: Some(ex.clone()),
        region: Region::Texture,
        scale: 0.5,
        ..ExemplarSettings::default()
    };
    app.start_exemplar(&settings);
    let job = app.tool.take().expect("started");
    let out = job.wait().unwrap();
    let history = app.state.history_len().0;
    app.state.apply_tool_outcome(out);
    assert!(app.state.errors.is_empty(), "{:?}", app.state.errors);
    assert_eq!(app.state.history_len().0, history + 1);
    let m = app.state.slot(Side::Target).unwrap().displayed().clone();
    // The same mesh and UVs, a new texture of the exemplar's green.
    assert_eq!(m.faces, before.faces);
    assert_eq!(m.uvs, before.uvs);
    let tex = &m.texture.as_ref().expect("a texture").image;
    assert_eq!(tex.dimensions(), (TEXTURE_SIDE, TEXTURE_SIDE));
    let green = tex
        .pixels()
        .filter(|p| p.0[1] > 140 && p.0[0] < 70 && p.0[2] < 80)
        .count();
    assert!(
        green as f64 > 0.95 * (TEXTURE_SIDE as f64).powi(2),
        "{green} green texels"
    );
    assert!(
        app.state.message.contains("patches pasted"),
        "{}",
        app.state.message
    );
    // One undo brings Spot's own texture back.
    assert!(app.state.undo());
    let back = app.state.slot(Side::Target).unwrap().displayed().clone();
    assert!(
        std::sync::Arc::ptr_eq(back.texture.as_ref().unwrap(), &own)
            || back.texture.as_ref().unwrap().image == own.image
    );
    std::fs::remove_file(&ex).ok();
}

// ----- unsaved work: the dirty flag, the close prompt, autosave and recovery -----

/// Source and target spheres saved as files in `dir`, opened in a test app.
fn app_on_files(dir: &std::path::Path) -> App {
    let (src, tgt) = (dir.join("src.ply"), dir.join("tgt.ply"));
    meshmatch::mesh::io::save(&sphere(10, 12), &src).unwrap();
    meshmatch::mesh::io::save(&sphere(14, 18), &tgt).unwrap();
    let mut a = App::new(TestEngine::default(), None);
    a.state.open_mesh(Side::Source, &src).unwrap();
    a.state.open_mesh(Side::Target, &tgt).unwrap();
    a
}

/// The commands the app sent its window in the last frame.
fn window_commands(h: &Harness<'static, App>) -> Vec<egui::ViewportCommand> {
    h.output()
        .viewport_output
        .get(&egui::ViewportId::ROOT)
        .map(|v| v.commands.clone())
        .unwrap_or_default()
}

/// The window's close button (or the window manager) asks the app to close.
fn request_close(h: &mut Harness<'static, App>) {
    h.input_mut()
        .viewports
        .entry(egui::ViewportId::ROOT)
        .or_default()
        .events
        .push(egui::ViewportEvent::Close);
    h.step();
}

#[test]
fn every_edit_that_matters_marks_the_work_unsaved_and_saving_clears_it() {
    use meshmatch::app::tools::ToolOutcome;
    let dir = temp_dir("dirty");
    let session = dir.join("work.json");
    let mut a = app_on_files(&dir);
    wait_prepared(&mut a);
    let saved = |a: &mut App| {
        a.state.save_session_to(&session).unwrap();
        assert!(!a.state.is_dirty(), "clean after a save");
        assert_eq!(a.state.session_path(), Some(&session));
    };
    saved(&mut a);
    // correspondences: a click on each side adds a pair
    a.state.click_vertex(Side::Source, 3, false);
    assert!(a.state.is_dirty(), "a pending source click");
    a.state.click_vertex(Side::Target, 5, false);
    assert_eq!(a.state.corr.len(), 1);
    saved(&mut a);
    // moving a marker through a drag: the later moves of the drag count too
    let sel = Selection {
        pair: 0,
        side: Side::Target,
        k: 0,
    };
    a.state.move_marker(sel, 6, true);
    saved(&mut a);
    a.state.move_marker(sel, 7, false);
    assert!(a.state.is_dirty(), "a drag's later move");
    saved(&mut a);
    // paint: the first dab of a stroke and the later ones
    a.state.paint_at(Side::Target, [0.0, 1.0, 0.0], true);
    assert!(a.state.is_dirty(), "a stroke");
    saved(&mut a);
    assert!(a.state.paint_at(Side::Target, [0.0, 0.9, 0.4], false) > 0);
    assert!(a.state.is_dirty(), "a stroke's later dab");
    saved(&mut a);
    // parameters
    let mut p = a.state.params.clone();
    p.iterations += 1;
    a.state.set_params(p.clone(), Instant::now());
    assert!(a.state.is_dirty(), "a parameter");
    saved(&mut a);
    a.state.set_params(p, Instant::now());
    assert!(
        !a.state.is_dirty(),
        "the same parameters again change nothing"
    );
    // undo and redo change the work
    assert!(a.state.undo());
    assert!(a.state.is_dirty(), "undo");
    saved(&mut a);
    assert!(a.state.redo());
    assert!(a.state.is_dirty(), "redo");
    saved(&mut a);
    // tools' results: colours, pairs, a new mesh
    let n = a
        .state
        .slot(Side::Source)
        .unwrap()
        .displayed()
        .num_vertices();
    a.state.apply_tool_outcome(ToolOutcome::Colors(
        Side::Source,
        vec![[0.2, 0.4, 0.6]; n],
        "completed".into(),
    ));
    assert!(a.state.is_dirty(), "a tool's colours");
    saved(&mut a);
    a.state.apply_tool_outcome(ToolOutcome::Correspondences(
        vec![Correspondence {
            source_vertex: 1,
            target_vertices: vec![2],
        }],
        "suggested".into(),
    ));
    assert!(a.state.is_dirty(), "suggested pairs");
    saved(&mut a);
    // Not edits: selecting, the brush, a finished transfer, a deleted nothing.
    a.state.select(Some(sel));
    a.state.brush.radius = 0.2;
    a.state.schedule_restart(Instant::now());
    let job = a.state.job.job;
    let t0 = Instant::now();
    while !(a.state.job.job > job && !a.state.job.running && a.state.result.is_some()) {
        assert!(t0.elapsed() < Duration::from_secs(10), "no transfer");
        a.wait_events(Duration::from_millis(20));
        a.pump(Instant::now() + Duration::from_secs(1));
    }
    assert!(
        !a.state.is_dirty(),
        "a selection, the brush or a transfer result is no unsaved work"
    );
    // A computed mesh (a tool's new geometry) is saved beside the session and comes back.
    let mut bumpy = sphere(9, 11);
    for p in &mut bumpy.positions {
        p[1] *= 1.5;
    }
    bumpy.path = Some(dir.join("src.ply"));
    a.state.apply_tool_outcome(ToolOutcome::Mesh(
        Side::Source,
        bumpy.clone(),
        "detail".into(),
    ));
    assert!(a.state.is_dirty(), "a tool's new mesh");
    assert!(
        a.state
            .work_summary()
            .contains(&"a computed source mesh".to_string()),
        "{:?}",
        a.state.work_summary()
    );
    saved(&mut a);
    assert!(dir.join("work.source_mesh.ply").is_file());
    let mut b = App::new(TestEngine::default(), None);
    b.state.open_session(&session).unwrap();
    assert!(!b.state.is_dirty(), "an opened session is saved work");
    assert_eq!(
        b.state.slot(Side::Source).unwrap().file.positions,
        bumpy.positions,
        "the computed mesh, not the file it started from"
    );
}

#[test]
fn closing_with_unsaved_work_asks_save_dont_save_or_cancel() {
    let dir = temp_dir("close_prompt");
    let session = dir.join("work.json");
    let mut a = app_on_files(&dir);
    a.state.mark_saved(None);
    let mut h = harness(a);
    h.step();
    // Nothing unsaved: the window closes without a question.
    request_close(&mut h);
    assert!(h.state().close_allowed());
    assert!(!window_commands(&h).contains(&egui::ViewportCommand::CancelClose));

    // A pair added: closing is held back and the prompt asks.
    let mut a = app_on_files(&dir);
    a.state.mark_saved(None);
    let mut h = harness(a);
    h.step();
    let (s, t) = (
        front_vertex(&h, Side::Source, 0),
        front_vertex(&h, Side::Target, 0),
    );
    click_vertex(&mut h, Side::Source, s, egui::Modifiers::NONE);
    click_vertex(&mut h, Side::Target, t, egui::Modifiers::NONE);
    assert_eq!(h.state().state.corr.len(), 1);
    request_close(&mut h);
    assert!(window_commands(&h).contains(&egui::ViewportCommand::CancelClose));
    assert!(!h.state().close_allowed());
    h.step();
    assert!(
        h.query_by_label_contains("Save your work before closing")
            .is_some()
    );
    assert!(
        h.query_by_label_contains("1 correspondence pairs")
            .is_some()
    );
    // Escape cancels: the window stays, the work too.
    h.key_press(egui::Key::Escape);
    h.step();
    assert!(
        h.query_by_label_contains("Save your work before closing")
            .is_none()
    );
    assert!(!h.state().close_allowed());
    assert_eq!(h.state().state.corr.len(), 1);
    // Save with no session file yet asks where (the built-in browser here), then closes.
    h.state_mut().files.native = false;
    request_close(&mut h);
    h.step();
    h.get_by_label("Save").click();
    h.run_steps(3);
    assert!(h.state().files.browsing(), "the Save dialog opens");
    assert!(!h.state().close_allowed());
    // Type the file's path into the browser's File field and press its Save.
    h.get_all_by_role(egui::accesskit::Role::TextInput)
        .nth(1)
        .unwrap()
        .focus();
    h.step();
    h.get_all_by_role(egui::accesskit::Role::TextInput)
        .nth(1)
        .unwrap()
        .type_text(&format!("{}", session.display()));
    h.step();
    h.get_by_label("Save").click();
    h.step();
    assert!(
        session.is_file(),
        "saved where chosen ({:?}, browsing {})",
        h.state().state.errors,
        h.state().files.browsing()
    );
    assert!(h.state().close_allowed(), "and then closing");
    assert!(window_commands(&h).contains(&egui::ViewportCommand::Close));
    assert!(!h.state().state.is_dirty());

    // "Don't save" closes and leaves the file as it was.
    let mut a = App::new(TestEngine::default(), None);
    a.state.open_session(&session).unwrap();
    let before = std::fs::read(&session).unwrap();
    let mut h = harness(a);
    h.step();
    h.state_mut().state.delete_pair(0);
    request_close(&mut h);
    h.step();
    h.get_by_label("Don't save").click();
    h.step();
    assert!(h.state().close_allowed());
    h.step();
    assert_eq!(std::fs::read(&session).unwrap(), before);

    // With a session file, Save writes it and closes.
    let mut a = App::new(TestEngine::default(), None);
    a.state.open_session(&session).unwrap();
    let mut h = harness(a);
    h.step();
    h.state_mut().state.delete_pair(0);
    request_close(&mut h);
    h.step();
    h.key_press(egui::Key::Enter);
    h.step();
    h.step();
    assert!(h.state().close_allowed());
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&session).unwrap()).unwrap();
    assert_eq!(
        s["correspondences"]["correspondences"]
            .as_array()
            .unwrap()
            .len(),
        0
    );
}

#[test]
fn opening_a_scene_or_a_new_session_over_unsaved_work_asks_first() {
    let mut h = harness(app_with_scene(TestEngine::default()));
    h.state_mut().load_demo(0).unwrap();
    h.step();
    assert!(
        !h.state().state.is_dirty(),
        "a scene as it comes is no work"
    );
    h.state_mut().state.delete_pair(0);
    assert_eq!(h.state().state.corr.len(), 1);
    h.state_mut()
        .guard(meshmatch::app::unsaved::Guarded::Scene(0));
    h.run_steps(2);
    assert!(
        h.query_by_label_contains("before opening the scene")
            .is_some()
    );
    h.key_press(egui::Key::Escape);
    h.step();
    assert_eq!(h.state().state.corr.len(), 1, "cancel keeps the work");
    h.state_mut()
        .guard(meshmatch::app::unsaved::Guarded::Scene(0));
    h.run_steps(2);
    h.get_by_label("Don't save").click();
    h.step();
    assert_eq!(h.state().state.corr.len(), 2, "the scene again");
    // New on saved work: no question, empty views.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::N);
    h.step();
    assert!(h.query_by_label_contains("Unsaved work").is_none());
    assert!(h.state().state.meshes.iter().all(Option::is_none));
    assert!(h.state().state.corr.is_empty());
}

/// The autosave folders under `root`, each with its session files.
fn autosaves(root: &std::path::Path) -> Vec<(std::path::PathBuf, Vec<String>)> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(root.join("autosave"))
        .into_iter()
        .flatten()
        .flatten()
    {
        let mut names: Vec<String> = std::fs::read_dir(e.path())
            .unwrap()
            .flatten()
            .map(|f| f.file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".json"))
            .collect();
        names.sort();
        out.push((e.path(), names));
    }
    out
}

#[test]
fn autosave_writes_only_changes_and_a_killed_app_is_recovered() {
    use meshmatch::app::tools::ToolOutcome;
    let dir = temp_dir("autosave");
    let root = dir.join("data");
    let mut a = app_on_files(&dir);
    wait_prepared(&mut a);
    a.state.mark_saved(None);
    let mut h = harness(a.with_autosave(&root, Duration::ZERO));
    h.step();
    let folders = autosaves(&root);
    assert_eq!(folders.len(), 1);
    assert!(folders[0].1.is_empty(), "nothing unsaved, nothing written");
    // Work: a computed source mesh, pairs, paint on both sides, a parameter.
    let mut bumpy = sphere(9, 11);
    for p in &mut bumpy.positions {
        p[0] *= 1.3;
    }
    let st = &mut h.state_mut().state;
    st.apply_tool_outcome(ToolOutcome::Mesh(
        Side::Source,
        bumpy.clone(),
        "detail".into(),
    ));
    st.click_vertex(Side::Source, 3, false);
    st.click_vertex(Side::Target, 5, false);
    st.click_vertex(Side::Source, 40, false);
    st.click_vertex(Side::Target, 90, false);
    let mut p = st.params.clone();
    p.iterations = 7;
    st.set_params(p.clone(), Instant::now());
    h.step();
    let t0 = Instant::now();
    while h
        .state()
        .state
        .meshes
        .iter()
        .any(|m| m.as_ref().is_none_or(|s| s.working.is_none()))
    {
        assert!(t0.elapsed() < Duration::from_secs(10));
        h.step();
        std::thread::sleep(Duration::from_millis(20));
    }
    let st = &mut h.state_mut().state;
    st.brush.radius = 0.3;
    st.brush.color = [0.0, 1.0, 0.0];
    st.paint_at(Side::Target, [0.0, 1.0, 0.0], true);
    st.brush.color = [1.0, 1.0, 0.0];
    st.paint_at(Side::Source, [0.0, -1.0, 0.0], true);
    h.step();
    let folders = autosaves(&root);
    let gen1 = folders[0].1.clone();
    assert_eq!(gen1.len(), 1, "one session autosaved: {gen1:?}");
    h.step();
    h.step();
    assert_eq!(autosaves(&root)[0].1, gen1, "no change, no new autosave");
    // (the transfer result arriving is no change either)
    h.state_mut()
        .state
        .paint_at(Side::Target, [0.0, 0.95, 0.3], false);
    h.step();
    let gen2 = autosaves(&root)[0].1.clone();
    assert_eq!(gen2.len(), 1, "the older generation is removed: {gen2:?}");
    assert_ne!(gen2, gen1, "a change, a new autosave");
    let want_corr = h.state().state.corr.clone();
    let want_paint = [Side::Source, Side::Target]
        .map(|s| h.state().state.slot(s).unwrap().paint.clone().unwrap());
    // While the app runs its autosave is nobody's to recover.
    assert!(meshmatch::app::autosave::orphans(&root).is_empty());

    // Killed: no clean exit (the lock goes with the process, the folder stays).
    drop(h);
    let orphan = autosaves(&root);
    assert_eq!(orphan.len(), 1);

    // The next start offers it; Recover brings the work back as unsaved work.
    let mut b =
        App::new(TestEngine::default(), None).with_autosave(&root, Duration::from_secs(3600));
    assert_eq!(b.safety.recoveries.len(), 1);
    b.state.mark_saved(None);
    let mut h = harness(b);
    h.step();
    assert!(h.query_by_label_contains("Recover unsaved work?").is_some());
    assert!(
        h.query_by_label_contains("2 correspondence pairs")
            .is_some()
    );
    assert!(
        h.query_by_label_contains("source: a computed mesh, painted")
            .is_some()
    );
    h.get_by_label("Recover").click();
    h.step();
    h.step();
    let st = &h.state().state;
    assert_eq!(st.corr, want_corr, "the pairs");
    assert_eq!(st.params, p, "the parameters");
    assert!(
        st.is_dirty() && st.session_path().is_none(),
        "unsaved until saved"
    );
    assert_eq!(
        st.slot(Side::Source).unwrap().file.positions,
        bumpy.positions,
        "the computed mesh"
    );
    assert!(
        st.slot(Side::Source).unwrap().file.path.is_none(),
        "still computed"
    );
    for (i, side) in [Side::Source, Side::Target].into_iter().enumerate() {
        let got = st
            .slot(side)
            .unwrap()
            .paint
            .clone()
            .expect("paint recovered");
        assert_eq!(got.len(), want_paint[i].len());
        let worst = got
            .iter()
            .zip(&want_paint[i])
            .flat_map(|(g, w)| (0..4).map(move |k| (g[k] - w[k]).abs()))
            .fold(0.0f32, f32::max);
        assert!(worst <= 1.0 / 255.0 + 1e-6, "{side:?} paint off by {worst}");
    }
    // The dead app's folder is gone; this app's autosave holds the work at once.
    let now = autosaves(&root);
    assert_eq!(now.len(), 1);
    assert_ne!(now[0].0, orphan[0].0);
    assert_eq!(now[0].1.len(), 1, "recovered work autosaved at once");
    // A clean exit leaves nothing to recover.
    h.state_mut().finish_autosave();
    assert!(autosaves(&root).is_empty());
    let c = App::new(TestEngine::default(), None).with_autosave(&root, Duration::ZERO);
    assert!(c.safety.recoveries.is_empty());
    drop(c);

    // Discard deletes the autosave and keeps the state.
    let mut a = app_on_files(&dir);
    a.state.mark_saved(None);
    let mut h = harness(a.with_autosave(&root, Duration::ZERO));
    h.step();
    h.state_mut().state.click_vertex(Side::Source, 3, false);
    h.state_mut().state.click_vertex(Side::Target, 5, false);
    h.step();
    drop(h);
    let mut b = app_on_files(&dir).with_autosave(&root, Duration::ZERO);
    b.state.mark_saved(None);
    let mut h = harness(b);
    h.step();
    h.get_by_label("Discard").click();
    h.step();
    assert!(h.state().state.corr.is_empty());
    assert_eq!(autosaves(&root).len(), 1, "only this app's folder");
    // Saving the work drops the autosave: the user's file holds it.
    h.state_mut().state.click_vertex(Side::Source, 3, false);
    h.step();
    assert_eq!(autosaves(&root)[0].1.len(), 1);
    h.state_mut()
        .state
        .save_session_to(&dir.join("saved.json"))
        .unwrap();
    h.step();
    assert!(
        autosaves(&root)[0].1.is_empty(),
        "saved work is not autosaved"
    );
}
