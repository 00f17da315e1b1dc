//! The applications as app actions (MeshMatch §5.3-5.4): completion from the paint layer,
//! texture update for new geometry and detail transfer, and texture synthesis from an image
//! exemplar (Wei & Levoy 2001), each run on its own thread with progress and cancel while the
//! window stays responsive.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use crossbeam_channel::{Receiver, bounded};

use crate::applications::{DETAIL_SHAPE_WEIGHT, complete, transfer_detail, update_texture};
use crate::correspondence::Side;
use crate::error::{Error, Result};
use crate::mesh::TriMesh;
use crate::meshmatch::TransferParams;
use crate::synthesis::{Orientation, Search, SynthParams, exemplar};
use crate::work::{CancelToken, Event};

/// Working vertices of the applications started from the app (a responsive default; the CLI
/// takes `--vertices`).
pub const TOOL_VERTICES: usize = 32_000;

/// What a finished tool hands back to the app.
#[derive(Debug)]
pub enum ToolOutcome {
    /// New colours for every displayed vertex of one side (applied as a paint layer, undoable),
    /// with the status message to show.
    Colors(Side, Vec<[f32; 3]>, String),
    /// A new mesh for one side (replaces it).
    Mesh(Side, TriMesh, String),
    /// Suggested correspondences (file vertices) to add to the existing ones, as one undo step.
    Correspondences(Vec<crate::correspondence::Correspondence>, String),
    /// Nothing to apply (a file was written): the status message to show.
    Done(String),
    /// Per-corner UVs (a generated atlas) for the displayed mesh of one side, identified by its
    /// slot's id, with the status message to show.
    Uvs(Side, u64, Vec<[f32; 2]>, String),
}

/// A partial result: colours per vertex of the tool's working mesh.
pub type Partial = Arc<[[f32; 3]]>;

/// The chosen image's path and its size in pixels, or why its header cannot be read.
type ImageSize = (PathBuf, std::result::Result<(u32, u32), String>);

/// A running tool.
pub struct ToolJob {
    /// What it does, for the status bar.
    pub name: &'static str,
    /// Cancels it.
    pub cancel: CancelToken,
    /// When it started.
    pub started: Instant,
    /// Latest progress fraction (0..1).
    pub fraction: Arc<Mutex<f32>>,
    /// The side whose displayed vertices are the first vertices of every partial result, for
    /// tools that stream partial results (`None`: partials are not previewed).
    pub preview: Option<Side>,
    /// Latest partial result not yet taken by [`ToolJob::take_partial`].
    partial: Arc<Mutex<Option<Partial>>>,
    rx: Receiver<Result<ToolOutcome>>,
}

impl ToolJob {
    /// Run `f` on a new thread; `wake` is called on progress and when it ends.
    pub fn spawn(
        name: &'static str,
        wake: impl Fn() + Send + Sync + 'static,
        f: impl FnOnce(&dyn Fn(Event), &CancelToken) -> Result<ToolOutcome> + Send + 'static,
    ) -> ToolJob {
        let (tx, rx) = bounded(1);
        let cancel = CancelToken::new();
        let fraction = Arc::new(Mutex::new(0.0f32));
        let partial = Arc::new(Mutex::new(None));
        let (c, fr, pa) = (cancel.clone(), fraction.clone(), partial.clone());
        std::thread::Builder::new()
            .name(format!("meshmatch-{name}"))
            .spawn(move || {
                crate::work::lower_thread_priority();
                let sink = |e: Event| {
                    let p = match e {
                        Event::Progress(p) => p,
                        Event::Partial { progress, signal } => {
                            if let Ok(mut s) = pa.lock() {
                                *s = Some(signal);
                            }
                            progress
                        }
                        Event::StageTime(..) => return,
                    };
                    if let Ok(mut f) = fr.lock() {
                        *f = p.fraction;
                    }
                    wake();
                };
                let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(&sink, &c)))
                    .unwrap_or_else(|_| Err(Error::InvalidInput(format!("{name} failed"))));
                let _ = tx.send(r);
                wake();
            })
            .expect("spawn a tool thread");
        ToolJob {
            name,
            cancel,
            started: Instant::now(),
            fraction,
            preview: None,
            partial,
            rx,
        }
    }

    /// The latest partial result since the last call, if any (colours per vertex of the tool's
    /// working mesh; its first vertices are the displayed ones of [`ToolJob::preview`]).
    pub fn take_partial(&self) -> Option<Partial> {
        self.partial.lock().ok().and_then(|mut p| p.take())
    }

    /// The outcome once it has finished.
    pub fn poll(&self) -> Option<Result<ToolOutcome>> {
        self.rx.try_recv().ok()
    }

    /// Block until it finishes (tests and scripts).
    pub fn wait(&self) -> Result<ToolOutcome> {
        self.rx
            .recv()
            .unwrap_or_else(|_| Err(Error::InvalidInput("tool thread vanished".into())))
    }
}

fn params(vertices: usize) -> TransferParams {
    TransferParams {
        vertices,
        ..TransferParams::default()
    }
}

/// Completion by example of a painted mesh: vertices whose paint coverage is below one half are
/// synthesised from the painted ones. `painted` is the displayed mesh with its displayed colours,
/// `coverage` the paint coverage per displayed vertex; the outcome colours every displayed vertex.
pub fn completion_job(
    side: Side,
    painted: TriMesh,
    coverage: Vec<f32>,
    wake: impl Fn() + Send + Sync + 'static,
) -> Result<ToolJob> {
    let synth: Vec<bool> = coverage.iter().map(|&c| c < 0.5).collect();
    let example = synth.iter().filter(|s| !**s).count();
    if example < 3 || example == synth.len() {
        return Err(Error::InvalidInput(
            "paint part of the mesh first: the painted part is the example, the rest is completed"
                .into(),
        ));
    }
    let n = painted.num_vertices();
    Ok(ToolJob::spawn("completion", wake, move |sink, cancel| {
        let r = complete(&painted, &synth, &params(n), sink, cancel)?;
        Ok(ToolOutcome::Colors(
            side,
            r.colors,
            format!("{side:?} completed from its paint (Ctrl+Z undoes)"),
        ))
    }))
}

/// A UV atlas for a `texture_size`² texel layer on `mesh` (one side's displayed mesh, its slot
/// `id`), so that a mesh without UVs can be painted at texel resolution.
pub fn atlas_job(
    side: Side,
    id: u64,
    mesh: Arc<TriMesh>,
    texture_size: u32,
    wake: impl Fn() + Send + Sync + 'static,
) -> ToolJob {
    ToolJob::spawn("UV atlas", wake, move |_sink, cancel| {
        let params = crate::geometry::AtlasParams {
            texture_size,
            ..Default::default()
        };
        let a = crate::geometry::uv_atlas(&mesh.positions, &mesh.faces, &params, &|_| {}, cancel)?;
        Ok(ToolOutcome::Uvs(
            side,
            id,
            a.uvs,
            format!(
                "{side:?}: UV atlas of {} charts ({:.0}% of the texture); strokes now paint texels",
                a.charts,
                100.0 * a.utilization
            ),
        ))
    })
}

/// Texture update: `old` (textured) re-applied to `new` geometry; the outcome replaces the target.
pub fn update_job(old: TriMesh, new: TriMesh, wake: impl Fn() + Send + Sync + 'static) -> ToolJob {
    ToolJob::spawn("texture update", wake, move |sink, cancel| {
        let r = update_texture(&old, &new, &params(TOOL_VERTICES), sink, cancel)?;
        let changed = r.changed.iter().filter(|c| **c).count();
        let mut m = new;
        m.colors = Some(r.colors);
        m.texture = None;
        m.uvs = None;
        Ok(ToolOutcome::Mesh(
            Side::Target,
            m,
            format!("texture updated: {changed} vertices synthesised, the rest copied"),
        ))
    })
}

/// What the app's transfer moves from the source onto the target.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Signal {
    /// Colours (the live MeshMatch transfer, restarted on every parameter edit).
    #[default]
    Colour,
    /// Geometric detail (MeshMatch §5.3): the source's displacement over its smoothed surface,
    /// applied along the target's normals; run on demand, it replaces the target.
    Detail,
}

/// Largest detail strength the parameters panel offers.
pub const MAX_DETAIL_STRENGTH: f32 = 3.0;

/// The signal choice of the parameters panel and the detail transfer's strength.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SignalSettings {
    /// What the panel's transfer button moves.
    pub signal: Signal,
    /// Multiplier of the transferred displacement (1 = the source's amplitude, relative to
    /// each mesh's mean edge length; 0 = none; negative engraves instead of embossing).
    pub strength: f32,
}

impl Default for SignalSettings {
    fn default() -> Self {
        SignalSettings {
            signal: Signal::Colour,
            strength: 1.0,
        }
    }
}

impl SignalSettings {
    /// Draw the signal selector and, for detail, the strength slider (with tooltips).
    pub fn ui(&mut self, ui: &mut eframe::egui::Ui) {
        use eframe::egui;
        ui.horizontal(|ui| {
            ui.label("Signal:");
            ui.selectable_value(&mut self.signal, Signal::Colour, "colour")
                .on_hover_text("Transfer the source's colours onto the target (live)");
            ui.selectable_value(&mut self.signal, Signal::Detail, "detail")
                .on_hover_text(
                    "Transfer the source's fine geometric detail onto the target's surface \
                     (MeshMatch §5.3); the displaced target replaces the target",
                );
        });
        if self.signal == Signal::Detail {
            ui.add(
                egui::Slider::new(
                    &mut self.strength,
                    -MAX_DETAIL_STRENGTH..=MAX_DETAIL_STRENGTH,
                )
                .text("strength"),
            )
            .on_hover_text(
                "Scale of the transferred displacement: 1 = the source's amplitude relative to \
                 its edge length, 0 = none, negative values engrave instead of emboss",
            );
        }
    }
}

/// Detail transfer from the source's geometry onto the target's, the displacement scaled by
/// `strength`; the outcome replaces the target.
pub fn detail_job(
    source: TriMesh,
    target: TriMesh,
    strength: f32,
    wake: impl Fn() + Send + Sync + 'static,
) -> ToolJob {
    ToolJob::spawn("detail transfer", wake, move |sink, cancel| {
        let p = TransferParams {
            shape_weight: DETAIL_SHAPE_WEIGHT,
            ..params(TOOL_VERTICES)
        };
        let r = transfer_detail(&source, &target, strength, &p, sink, cancel)?;
        let n = r.mesh.num_vertices();
        Ok(ToolOutcome::Mesh(
            Side::Target,
            r.mesh,
            format!("detail transferred onto the target ({n} vertices, strength {strength})"),
        ))
    })
}

/// Pairs "Suggest correspondences" adds.
pub const SUGGESTED_PAIRS: usize = 6;

/// Suggest `count` well-spread correspondences from the global shape map
/// ([`crate::meshmatch::map_meshes`], the existing pairs as landmarks): target vertices by
/// farthest-point sampling (away from the existing target markers too) among the vertices the
/// map and the map back agree on (within [`CYCLE_TOLERANCE`]), each paired with its mapped source
/// vertex.
pub fn suggest_job(
    source: TriMesh,
    target: TriMesh,
    existing: Vec<crate::correspondence::Correspondence>,
    count: usize,
    wake: impl Fn() + Send + Sync + 'static,
) -> ToolJob {
    ToolJob::spawn("suggest correspondences", wake, move |sink, cancel| {
        let progress = |f: f32| {
            sink(Event::Progress(crate::work::Progress {
                stage: "global map",
                fraction: f,
                ..Default::default()
            }))
        };
        progress(0.05);
        let m = crate::meshmatch::map_meshes(&source, &target, &existing, cancel)?;
        progress(0.5);
        // The map back, for a cycle-consistency check: only target vertices that come back
        // close to themselves are suggested (maps err most at thin extremities).
        let reversed: Vec<crate::correspondence::Correspondence> = existing
            .iter()
            .flat_map(|c| {
                c.target_vertices
                    .iter()
                    .map(move |&t| crate::correspondence::Correspondence {
                        source_vertex: t,
                        target_vertices: vec![c.source_vertex],
                    })
            })
            .collect();
        let back = crate::meshmatch::map_meshes(&target, &source, &reversed, cancel)?;
        progress(0.9);
        let file_pos = file_positions(&target);
        let diag = target
            .bounds()
            .map(|(lo, hi)| (0..3).map(|i| (hi[i] - lo[i]).powi(2)).sum::<f32>().sqrt())
            .unwrap_or(0.0);
        let consistent: Vec<bool> = (0..target.positions.len())
            .map(|v| {
                let f = target.file_index.get(v).copied().unwrap_or(v as u32) as usize;
                let s = m.target_to_source.get(f).copied().unwrap_or(0) as usize;
                let r = back.target_to_source.get(s).copied().unwrap_or(0) as usize;
                match (file_pos.get(f), file_pos.get(r)) {
                    (Some(a), Some(b)) => {
                        (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f32>().sqrt()
                            <= CYCLE_TOLERANCE * diag
                    }
                    _ => false,
                }
            })
            .collect();
        let seeds: Vec<u32> = existing
            .iter()
            .flat_map(|c| c.target_vertices.iter().copied())
            .collect();
        let picks = farthest_points(&target, &seeds, &consistent, count);
        let pairs: Vec<crate::correspondence::Correspondence> = picks
            .into_iter()
            .filter_map(|t| {
                let f = target.file_index.get(t as usize).copied().unwrap_or(t);
                m.target_to_source
                    .get(f as usize)
                    .map(|&s| crate::correspondence::Correspondence {
                        source_vertex: s,
                        target_vertices: vec![f],
                    })
            })
            .collect();
        let quality = if m.score >= crate::meshmatch::AUTO_SCORE_MIN {
            "similar shapes"
        } else {
            "the shapes differ: check each pair"
        };
        let msg = format!(
            "{} pairs suggested from the global map (isometry score {:.2}, {quality}); move or delete any",
            pairs.len(),
            m.score
        );
        Ok(ToolOutcome::Correspondences(pairs, msg))
    })
}

/// A suggested target vertex must come back through the map and the map back to within this
/// fraction of the target's bounding-box diagonal.
pub const CYCLE_TOLERANCE: f32 = 0.02;

/// Position of every file vertex (the first input vertex of each).
fn file_positions(mesh: &TriMesh) -> Vec<[f32; 3]> {
    let nf = mesh.file_vertex_count.max(mesh.positions.len());
    let mut out = vec![[f32::NAN; 3]; nf];
    for (i, p) in mesh.positions.iter().enumerate().rev() {
        let f = mesh.file_index.get(i).copied().unwrap_or(i as u32) as usize;
        if f < nf {
            out[f] = *p;
        }
    }
    out
}

/// `count` vertices of `mesh` among the `allowed` ones by farthest-point sampling (Euclidean),
/// starting away from `seeds` (file vertices) or, with none, from the centroid.
fn farthest_points(mesh: &TriMesh, seeds: &[u32], allowed: &[bool], count: usize) -> Vec<u32> {
    let p = &mesh.positions;
    if p.is_empty() {
        return Vec::new();
    }
    let d2 = |a: [f32; 3], b: [f32; 3]| (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f32>();
    let mut best = vec![f32::INFINITY; p.len()];
    let relax = |best: &mut [f32], q: [f32; 3]| {
        for (b, &x) in best.iter_mut().zip(p) {
            *b = b.min(d2(x, q));
        }
    };
    let seed_pos: Vec<[f32; 3]> = (0..p.len())
        .filter(|&v| {
            let f = mesh.file_index.get(v).copied().unwrap_or(v as u32);
            seeds.contains(&f)
        })
        .map(|v| p[v])
        .collect();
    for q in &seed_pos {
        relax(&mut best, *q);
    }
    if seed_pos.is_empty() {
        let n = p.len() as f32;
        let c = p.iter().fold([0.0f32; 3], |a, x| {
            [a[0] + x[0] / n, a[1] + x[1] / n, a[2] + x[2] / n]
        });
        relax(&mut best, c);
    }
    for (b, &ok) in best.iter_mut().zip(allowed) {
        if !ok {
            *b = f32::NEG_INFINITY;
        }
    }
    let mut out = Vec::with_capacity(count);
    for _ in 0..count {
        let Some((v, &d)) = best.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)) else {
            break;
        };
        if d <= 0.0 || !d.is_finite() {
            break;
        }
        out.push(v as u32);
        relax(&mut best, p[v]);
    }
    out
}

/// Where "Paint with exemplar" puts the texture.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Region {
    /// Every vertex of the mesh.
    Whole,
    /// Only the vertices painted with the Paint tool (coverage at least one half); the rest keep
    /// their displayed colours and constrain the synthesis at the border.
    Painted,
    /// The whole mesh, synthesized texel by texel into its texture (its own UVs, or an atlas
    /// generated for it): the mesh comes back textured, at [`TEXTURE_SIDE`]².
    Texture,
}

/// Side of the texture "Paint with exemplar" makes into a texture.
pub const TEXTURE_SIDE: u32 = 2048;

/// Settings of "Paint with exemplar" (texture synthesis from an image, Wei & Levoy 2001).
#[derive(Clone, Debug, PartialEq)]
pub struct ExemplarSettings {
    /// The exemplar image (PNG or JPEG); `None` until chosen.
    pub image: Option<PathBuf>,
    /// Which mesh to texture.
    pub side: Side,
    /// Whole mesh or only the painted region.
    pub region: Region,
    /// Exemplar width on the surface as a fraction of the mesh's bounding-box diagonal.
    pub scale: f32,
    /// Texture orientation field.
    pub orientation: Orientation,
    /// The exemplar is resized to this width in pixels (never enlarged); with `scale` it sets
    /// the texel spacing and so the number of synthesized vertices.
    pub pixels: u32,
    /// Best-match search strategy.
    pub search: Search,
    /// Random seed.
    pub seed: u64,
    /// Into a texture: paste whole patches of the image (lapped textures, which keep its
    /// contrast and large structures) instead of Wei-Levoy's texel-by-texel synthesis.
    pub patches: bool,
}

impl Default for ExemplarSettings {
    fn default() -> Self {
        ExemplarSettings {
            image: None,
            side: Side::Target,
            region: Region::Whole,
            scale: 0.25,
            orientation: Orientation::default(),
            pixels: 64,
            search: Search::default(),
            seed: 0,
            patches: true,
        }
    }
}

impl ExemplarSettings {
    /// Synthesized vertex count to expect on `mesh` for an exemplar `width` pixels wide (the
    /// uniform density `1 / h^2` with texel spacing `h = scale * diagonal / width`).
    pub fn estimated_vertices(&self, mesh: &TriMesh, width: u32) -> usize {
        let Some((lo, hi)) = mesh.bounds() else {
            return 0;
        };
        let diag = glam::Vec3::from(hi).distance(glam::Vec3::from(lo)) as f64;
        let h = self.scale as f64 * diag / width.clamp(1, self.pixels.max(1)) as f64;
        if h > 0.0 {
            (mesh.area() / (h * h)).max(mesh.num_vertices() as f64) as usize
        } else {
            0
        }
    }
}

/// Load an exemplar image and shrink it to at most `pixels` wide (aspect kept).
pub fn load_exemplar(
    path: &std::path::Path,
    pixels: u32,
) -> Result<(image::RgbImage, Option<image::GrayImage>)> {
    use crate::synthesis::exemplar::{resize_alpha, shrink_exemplar};
    let (tex, alpha) = crate::mesh::io::load_texture_with_alpha(path)?;
    let img = shrink_exemplar(tex.image, pixels);
    let alpha = alpha.map(|a| resize_alpha(a, img.width(), img.height()));
    Ok((img, alpha))
}

/// Paint with exemplar: synthesize the image's texture over `mesh` (the displayed mesh of
/// `settings.side` with its displayed colours). `coverage` (paint coverage per displayed vertex)
/// limits it to the painted region when `settings.region` is [`Region::Painted`]. Partial results
/// stream after every pass (see [`ToolJob::take_partial`]); the outcome colours every displayed
/// vertex. The image is read on the tool's thread, so a bad file ends the job with an error.
pub fn exemplar_job(
    settings: &ExemplarSettings,
    mesh: TriMesh,
    coverage: &[f32],
    wake: impl Fn() + Send + Sync + 'static,
) -> Result<ToolJob> {
    let path = settings.image.clone().ok_or_else(|| {
        Error::InvalidInput("choose an exemplar image first (PNG or JPEG)".into())
    })?;
    if !(settings.scale.is_finite() && settings.scale > 0.0) {
        return Err(Error::InvalidInput(format!(
            "scale must be positive, got {}",
            settings.scale
        )));
    }
    let mask = match settings.region {
        Region::Whole | Region::Texture => None,
        Region::Painted => {
            let m: Vec<bool> = coverage.iter().map(|&c| c >= 0.5).collect();
            if !m.iter().any(|&b| b) {
                return Err(Error::InvalidInput(
                    "paint the region to texture first (Paint tool), or choose the whole mesh"
                        .into(),
                ));
            }
            Some(m)
        }
    };
    let (lo, hi) = mesh
        .bounds()
        .ok_or_else(|| Error::InvalidMesh("the mesh is empty".into()))?;
    let diag = glam::Vec3::from(hi).distance(glam::Vec3::from(lo));
    let side = settings.side;
    let params = SynthParams {
        scale: Some(settings.scale * diag),
        orientation: settings.orientation,
        search: settings.search,
        seed: settings.seed,
        ..SynthParams::default()
    };
    let pixels = settings.pixels;
    let n = mesh.num_vertices();
    if settings.region == Region::Texture {
        return Ok(texture_job(
            path,
            params,
            settings.patches,
            mesh,
            side,
            wake,
        ));
    }
    let mut job = ToolJob::spawn("paint with exemplar", wake, move |sink, cancel| {
        let (img, alpha) = load_exemplar(&path, pixels)?;
        let input = exemplar::Input {
            exemplar: &img,
            target: &mesh,
            mask: mask.as_deref(),
            alpha: alpha.as_ref(),
        };
        let r = exemplar::run(&input, &params, sink, cancel)?;
        let colors = r
            .mesh
            .colors
            .as_ref()
            .map(|c| c[..n].to_vec())
            .ok_or_else(|| Error::InvalidInput("synthesis gave no colours".into()))?;
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        Ok(ToolOutcome::Colors(
            side,
            colors,
            format!(
                "{side:?} painted with {name} ({} vertices synthesized in {:.1} s; Ctrl+Z undoes)",
                r.mesh.num_vertices(),
                r.timings.total
            ),
        ))
    });
    job.preview = Some(side);
    Ok(job)
}

/// Paint with exemplar into a texture: the synthesis runs on the texels of `mesh`'s UV layout
/// (or a generated atlas) and reads the full-resolution image; the mesh comes back textured and
/// replaces the displayed one (one undo step).
fn texture_job(
    path: PathBuf,
    params: SynthParams,
    patches: bool,
    mesh: TriMesh,
    side: Side,
    wake: impl Fn() + Send + Sync + 'static,
) -> ToolJob {
    ToolJob::spawn("paint with exemplar", wake, move |sink, cancel| {
        let (tex, alpha) = crate::mesh::io::load_texture_with_alpha(&path)?;
        let mut target = mesh;
        target.colors = None;
        let input = exemplar::TextureInput {
            exemplar: &tex.image,
            alpha: alpha.as_ref(),
            target: &target,
            field: None,
        };
        let p = exemplar::TextureParams {
            synth: params,
            texture_size: TEXTURE_SIDE,
            ..Default::default()
        };
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        if patches {
            let r = exemplar::patch_pasting::paste_patches(
                &input,
                &p,
                &exemplar::patch_pasting::PatchParams::default(),
                sink,
                cancel,
            )?;
            let atlas = match &r.atlas_reason {
                Some(why) => format!("; a UV atlas was generated: {why}"),
                None => String::new(),
            };
            return Ok(ToolOutcome::Mesh(
                side,
                r.mesh,
                format!(
                    "{side:?} textured with {name}: {} patches pasted ({} made smaller to fit \
                     round parts) into a {TEXTURE_SIDE}x{TEXTURE_SIDE} texture in {:.1} \
                     s{atlas} (Ctrl+Z undoes)",
                    r.patches, r.shrunk, r.seconds
                ),
            ));
        }
        let r = exemplar::synthesize_texture(&input, &p, sink, cancel)?;
        let atlas = match &r.atlas_reason {
            Some(why) => format!("; a UV atlas was generated: {why}"),
            None => String::new(),
        };
        Ok(ToolOutcome::Mesh(
            side,
            r.mesh,
            format!(
                "{side:?} textured with {name}: {} texels synthesized into a {TEXTURE_SIDE}x\
                 {TEXTURE_SIDE} texture in {:.1} s{atlas} (Ctrl+Z undoes)",
                r.level_texels.first().copied().unwrap_or(0),
                r.timings.total
            ),
        ))
    })
}

/// The "Image: NAME  [Choose image...]" row of the image-exemplar windows; true when the button
/// was clicked.
pub fn image_chooser(
    ui: &mut eframe::egui::Ui,
    image: Option<&std::path::Path>,
    hover: &str,
) -> bool {
    let mut clicked = false;
    ui.horizontal(|ui| {
        let name = image.map_or("(no image chosen)".into(), |p| {
            p.file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned()
        });
        ui.label(format!("Image: {name}"));
        clicked = ui.button("Choose image...").on_hover_text(hover).clicked();
    });
    clicked
}

/// What the user asked for in the "Paint with exemplar" window.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExemplarAction {
    /// Nothing this frame.
    None,
    /// Run with the current settings.
    Run,
    /// Close the window.
    Close,
    /// Ask for the exemplar image (the app's file dialog).
    ChooseImage,
}

/// The "Paint with exemplar" window: its settings (kept between runs) and whether it is open.
#[derive(Clone, Debug, Default)]
pub struct ExemplarDialog {
    /// Shown this frame.
    pub open: bool,
    /// The settings the next run uses.
    pub settings: ExemplarSettings,
    /// Size of the chosen image (read from its header once per path), or why it cannot be read.
    size_of: Option<ImageSize>,
}

impl ExemplarDialog {
    /// Draw the settings with tooltips; returns what the user clicked. `busy`: a tool is running.
    ///
    /// The rows, each a function: [`image_size_row`], [`side_row`], [`region_row`],
    /// [`scale_rows`], [`orientation_combo`], [`search_row`], [`estimate_row`] and
    /// [`run_close_row`].
    pub fn ui<P: super::AppParams>(
        &mut self,
        ui: &mut eframe::egui::Ui,
        state: &super::AppState<P>,
        busy: bool,
    ) -> ExemplarAction {
        let s = &mut self.settings;
        let mut action = ExemplarAction::None;
        if image_chooser(
            ui,
            s.image.as_deref(),
            "A PNG or JPEG swatch: bricks, scales, fur, stripes...",
        ) {
            action = ExemplarAction::ChooseImage;
        }
        let width = image_size_row(ui, &mut self.size_of, s);
        ui.separator();
        side_row(ui, s);
        let painted = state
            .region_coverage(s.side)
            .map_or(0, |c| c.iter().filter(|&&c| c >= 0.5).count());
        region_row(ui, s, painted);
        scale_rows(ui, s);
        orientation_combo(ui, s);
        search_row(ui, s);
        let mesh = state.slot(s.side).map(|m| m.displayed());
        estimate_row(ui, s, mesh, width);
        let ready = s.image.is_some()
            && mesh.is_some()
            && !busy
            && (s.region != Region::Painted || painted > 0);
        let clicked = run_close_row(ui, ready);
        if clicked != ExemplarAction::None {
            action = clicked;
        }
        action
    }
}

/// The chosen image's size (read from its header once per path) or why it cannot be read;
/// returns the width the run uses (the image's, at most the settings' width).
fn image_size_row(
    ui: &mut eframe::egui::Ui,
    size_of: &mut Option<ImageSize>,
    s: &ExemplarSettings,
) -> u32 {
    if let Some(p) = &s.image
        && size_of.as_ref().is_none_or(|(q, _)| q != p)
    {
        let size = image::image_dimensions(p).map_err(|e| e.to_string());
        *size_of = Some((p.clone(), size));
    }
    let mut width = s.pixels;
    match size_of
        .as_ref()
        .filter(|(q, _)| Some(q) == s.image.as_ref())
    {
        Some((_, Ok((w, h)))) => {
            width = (*w).min(s.pixels);
            ui.label(format!("{w} x {h} pixels, used {width} wide"));
        }
        Some((_, Err(e))) => {
            ui.colored_label(eframe::egui::Color32::from_rgb(255, 120, 120), e);
        }
        None => {}
    }
    width
}

/// "Mesh:" which side to texture.
fn side_row(ui: &mut eframe::egui::Ui, s: &mut ExemplarSettings) {
    ui.horizontal(|ui| {
        ui.label("Mesh:");
        for side in [Side::Source, Side::Target] {
            ui.selectable_value(&mut s.side, side, format!("{side:?}"))
                .on_hover_text(format!("Texture the {side:?} mesh (left view = source)"));
        }
    });
}

/// "Apply to:" the whole mesh, the painted region (`painted` vertices) or a texture.
fn region_row(ui: &mut eframe::egui::Ui, s: &mut ExemplarSettings, painted: usize) {
    ui.horizontal(|ui| {
        ui.label("Apply to:");
        ui.selectable_value(&mut s.region, Region::Whole, "Whole mesh")
            .on_hover_text("Replace the colours of every vertex");
        ui.selectable_value(
            &mut s.region,
            Region::Painted,
            format!("Painted region ({painted} vertices)"),
        )
        .on_hover_text(
            "Only the vertices painted with the Paint tool (the mask layer's when it has \
             any paint, else the paint layer's); the rest keep their colours and guide the \
             border",
        );
        ui.selectable_value(&mut s.region, Region::Texture, "Into a texture")
            .on_hover_text(format!(
                "Synthesize texel by texel into a {TEXTURE_SIDE}x{TEXTURE_SIDE} texture \
                 through the mesh's UVs (or a generated atlas), from the full-resolution \
                 image; the mesh becomes textured"
            ));
    });
}

/// The scale slider, then whole patches (into a texture) or the exemplar's width (otherwise).
fn scale_rows(ui: &mut eframe::egui::Ui, s: &mut ExemplarSettings) {
    use eframe::egui;
    ui.add(
        egui::Slider::new(&mut s.scale, 0.02..=2.0)
            .logarithmic(true)
            .text("scale"),
    )
    .on_hover_text(
        "How wide the exemplar appears on the surface, as a fraction of the mesh's \
         bounding-box diagonal: smaller = more repetitions, finer texture",
    );
    if s.region == Region::Texture {
        ui.checkbox(&mut s.patches, "Paste whole patches")
            .on_hover_text(
                "Paste large discs of the image onto the surface, each placed where it matches \
                 its neighbours (lapped textures): keeps the image's contrast, large structures \
                 and sharpness. Off: Wei-Levoy synthesis texel by texel (finer mixing, softer)",
            );
    }
    if s.region != Region::Texture {
        ui.add(egui::Slider::new(&mut s.pixels, 32..=256).text("exemplar width (px)"))
            .on_hover_text(
                "The image is shrunk to this width before synthesis: more pixels = finer \
                 detail, but more surface vertices and a slower run (the count grows with \
                 its square)",
            );
    }
}

/// The orientation field's choice, each with what it suits.
fn orientation_combo(ui: &mut eframe::egui::Ui, s: &mut ExemplarSettings) {
    eframe::egui::ComboBox::from_label("orientation")
        .selected_text(s.orientation.as_str())
        .show_ui(ui, |ui| {
            for (o, tip) in [
                (
                    Orientation::Auto,
                    "Chosen from the image: random for isotropic textures, a smooth 2-way \
                     field for stripes, a 4-way one for grids and bricks",
                ),
                (
                    Orientation::Random,
                    "Random direction per vertex: for isotropic textures (noise, gravel, fur)",
                ),
                (
                    Orientation::Up,
                    "The texture's up follows the mesh's +Y axis: for textures with a \
                     natural up (grass, drips)",
                ),
                (
                    Orientation::Relax2,
                    "A smooth field with 2-way symmetry: for stripes",
                ),
                (
                    Orientation::Relax4,
                    "A smooth field with 4-way symmetry: for grids (bricks, tiles, weaves)",
                ),
            ] {
                ui.selectable_value(&mut s.orientation, o, o.as_str())
                    .on_hover_text(tip);
            }
        })
        .response
        .on_hover_text("How the texture is turned at each point of the surface");
}

/// "Search:" fast or exhaustive, and the seed.
fn search_row(ui: &mut eframe::egui::Ui, s: &mut ExemplarSettings) {
    ui.horizontal(|ui| {
        ui.label("Search:");
        ui.selectable_value(&mut s.search, Search::Fast, "fast")
            .on_hover_text("Coherence candidates + random search: nearly the same quality");
        ui.selectable_value(&mut s.search, Search::Exhaustive, "exhaustive")
            .on_hover_text("Every exemplar neighbourhood: the reference, many times slower");
        ui.add(eframe::egui::DragValue::new(&mut s.seed).prefix("seed "))
            .on_hover_text("Runs with the same seed and settings are identical");
    });
}

/// How much the run will synthesize on `mesh` (texels, or surface vertices at `width`), or that
/// a mesh is needed first.
fn estimate_row(
    ui: &mut eframe::egui::Ui,
    s: &ExemplarSettings,
    mesh: Option<&TriMesh>,
    width: u32,
) {
    match mesh {
        Some(_) if s.region == Region::Texture => {
            ui.label(format!(
                "up to {} texels synthesized, magnified to {TEXTURE_SIDE}x{TEXTURE_SIDE} from \
                 the full image",
                exemplar::DEFAULT_TEXEL_BUDGET
            ));
        }
        Some(m) => {
            let n = s.estimated_vertices(m, width);
            ui.label(format!(
                "about {n} surface vertices to synthesize (the view shows {})",
                m.num_vertices()
            ));
        }
        None => {
            ui.label(format!("open a {:?} mesh first", s.side));
        }
    }
}

/// The Run (enabled when `ready`) and Close buttons: which was clicked, if any.
fn run_close_row(ui: &mut eframe::egui::Ui, ready: bool) -> ExemplarAction {
    let mut action = ExemplarAction::None;
    ui.horizontal(|ui| {
        if ui
            .add_enabled(ready, eframe::egui::Button::new("Run"))
            .on_hover_text("Synthesize on its own thread; the view updates after every pass")
            .clicked()
        {
            action = ExemplarAction::Run;
        }
        if ui.button("Close").clicked() {
            action = ExemplarAction::Close;
        }
    });
    action
}
