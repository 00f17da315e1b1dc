//! The applications as app actions (MeshMatch §5.3-5.4): completion from the paint layer,
//! texture update for new geometry and detail transfer, each run on its own thread with
//! progress and cancel while the window stays responsive.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use crossbeam_channel::{Receiver, bounded};

use crate::applications::{DETAIL_SHAPE_WEIGHT, complete, transfer_detail, update_texture};
use crate::jobs::worker::Side;
use crate::jobs::{CancelToken, Event};
use crate::meshmatch::TransferParams;
use crate::{Error, Result, TriMesh};

/// Working vertices of the applications started from the app (a responsive default; the CLI
/// takes `--vertices`).
pub const TOOL_VERTICES: usize = 32_000;

/// What a finished tool hands back to the app.
#[derive(Debug)]
pub enum ToolOutcome {
    /// New colours for every displayed vertex of one side (applied as a paint layer, undoable).
    Colors(Side, Vec<[f32; 3]>),
    /// A new mesh for one side (replaces it).
    Mesh(Side, TriMesh, String),
}

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
        let (c, fr) = (cancel.clone(), fraction.clone());
        std::thread::Builder::new()
            .name(format!("meshmatch-{name}"))
            .spawn(move || {
                let sink = |e: Event| {
                    if let Event::Progress(p) = e {
                        if let Ok(mut f) = fr.lock() {
                            *f = p.fraction;
                        }
                        wake();
                    }
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
            rx,
        }
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
        Ok(ToolOutcome::Colors(side, r.colors))
    }))
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

/// Detail transfer from the source's geometry onto the target's; the outcome replaces the target.
pub fn detail_job(
    source: TriMesh,
    target: TriMesh,
    wake: impl Fn() + Send + Sync + 'static,
) -> ToolJob {
    ToolJob::spawn("detail transfer", wake, move |sink, cancel| {
        let p = TransferParams {
            shape_weight: DETAIL_SHAPE_WEIGHT,
            ..params(TOOL_VERTICES)
        };
        let r = transfer_detail(&source, &target, 1.0, &p, sink, cancel)?;
        let n = r.mesh.num_vertices();
        Ok(ToolOutcome::Mesh(
            Side::Target,
            r.mesh,
            format!("detail transferred onto the target ({n} vertices)"),
        ))
    })
}
