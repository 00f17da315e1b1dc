//! The transfer worker: one thread that owns the prepared meshes and runs jobs on request.
//!
//! The UI sends [`Command`]s over a crossbeam channel and polls [`WorkerEvent`]s; it never blocks.
//! Sending a command cancels the running job at once (through its [`CancelToken`], shared with the
//! UI thread), so a new request restarts the work. Prepared meshes are cached by mesh identity and
//! the preparation key of the parameters, so when only correspondences change only `solve` reruns.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

use crossbeam_channel::{Receiver, Sender, unbounded};

use crate::correspondence::Correspondence;
use crate::correspondence::Side;
use crate::error::{Error, Result};
use crate::mesh::TriMesh;
use crate::work::{CancelToken, Event};

/// The result of a solve, as the worker reports it.
#[derive(Clone, Debug)]
pub struct Solved {
    /// Per-vertex colour on the working target mesh.
    pub working_signal: Vec<[f32; 3]>,
    /// Per-vertex colour on the target file's vertices.
    pub file_signal: Vec<[f32; 3]>,
    /// Where the target's working faces lie in its file faces, to bake a texture into its UV
    /// layout on export; `None` from an engine without one (export then writes vertex colours).
    pub layout: Option<Arc<crate::meshmatch::BakeLayout>>,
    /// The source read at full resolution through the solution, for textures baked on export
    /// (`None` from an engine without one: export then interpolates `working_signal`).
    pub full: Option<Arc<crate::meshmatch::Resampler>>,
    /// The result as a texture in the target's own UV layout, for the view: the UVs of every
    /// working corner and the texture read from the source at full resolution (a target with
    /// UVs and a full-resolution result only).
    pub texture: Option<ResultTexture>,
}

/// A result texture and the UVs of every working corner in it.
pub type ResultTexture = (Arc<[[f32; 2]]>, Arc<crate::mesh::Texture>);

/// Texels per side of the texture a result is shown with: the target's own texture's size
/// where it has one, else this.
pub const VIEW_TEXTURE_SIZE: u32 = 2048;

/// The view texture of a solve (see [`Solved::texture`]).
fn view_texture(target: &TriMesh, solved: &Solved) -> Option<ResultTexture> {
    let (layout, full) = (solved.layout.as_ref()?, solved.full.as_ref()?);
    let uvs = layout.working_uvs(target)?;
    let size = target
        .texture
        .as_ref()
        .map(|t| t.image.width().max(t.image.height()).clamp(256, 8192))
        .unwrap_or(VIEW_TEXTURE_SIZE);
    let image = layout.bake_resampled(target, full, size);
    Some((
        uvs.into(),
        Arc::new(crate::mesh::Texture { image, path: None }),
    ))
}

/// The computation a worker runs: preparation of one mesh and the solve between two.
pub trait Engine: Send + 'static {
    /// Parameters of a transfer.
    type Params: Clone + Send + 'static;
    /// A mesh prepared for transfer (working mesh, hierarchy, features).
    type Prepared: Send + 'static;
    /// A key that changes exactly when `params` change what `prepare` produces.
    fn prepare_key(&self, params: &Self::Params) -> String;
    /// Prepare one mesh.
    fn prepare(
        &self,
        mesh: &TriMesh,
        params: &Self::Params,
        sink: &dyn Fn(Event),
        cancel: &CancelToken,
    ) -> Result<Self::Prepared>;
    /// Prepare a source and a target (both uncached); by default one after the other.
    fn prepare_pair(
        &self,
        source: &TriMesh,
        target: &TriMesh,
        params: &Self::Params,
        sink: &dyn Fn(Event),
        cancel: &CancelToken,
    ) -> Result<(Self::Prepared, Self::Prepared)> {
        let s = self.prepare(source, params, sink, cancel)?;
        let t = self.prepare(target, params, sink, cancel)?;
        Ok((s, t))
    }
    /// The working mesh of a prepared mesh, its working-to-file and file-to-working vertex maps.
    fn working(&self, prepared: &Self::Prepared) -> (Arc<TriMesh>, Arc<[u32]>, Arc<[u32]>);
    /// Transfer from `source` to `target` under correspondences in file vertex indices.
    fn solve(
        &self,
        source: &Self::Prepared,
        target: &Self::Prepared,
        corr: &[Correspondence],
        params: &Self::Params,
        sink: &dyn Fn(Event),
        cancel: &CancelToken,
    ) -> Result<Solved>;
}

/// What the UI asks the worker to do.
pub enum Command<P> {
    /// Replace the source mesh (identified by `id`, unique per loaded mesh).
    SetSource(u64, Arc<TriMesh>),
    /// Replace the target mesh.
    SetTarget(u64, Arc<TriMesh>),
    /// Start a transfer as job `job` (prepares what is not cached, then solves).
    StartTransfer {
        /// Job number chosen by the sender (see [`Worker::start`]).
        job: u64,
        /// Correspondences in file vertex indices.
        corr: Vec<Correspondence>,
        /// Transfer parameters.
        params: P,
    },
    /// Stop the running job.
    Cancel,
    /// End the worker thread.
    Shutdown,
}

/// What the worker reports.
#[derive(Clone, Debug)]
pub enum WorkerEvent {
    /// A mesh was prepared: its working mesh and working-to-file map (for display and picking).
    Prepared {
        /// Which mesh.
        side: Side,
        /// Identity of the mesh that was prepared.
        mesh_id: u64,
        /// The working-resolution mesh.
        working: Arc<TriMesh>,
        /// File vertex index of each working vertex.
        working_to_file: Arc<[u32]>,
        /// Working vertex index of each file vertex.
        file_to_working: Arc<[u32]>,
    },
    /// A progress or partial-result event of job `job`.
    Job {
        /// The job.
        job: u64,
        /// The event.
        event: Event,
    },
    /// Job `job` finished.
    Done {
        /// The job.
        job: u64,
        /// Its result.
        result: Arc<Solved>,
        /// Wall time in seconds.
        elapsed: f64,
    },
    /// Job `job` was cancelled.
    Cancelled {
        /// The job.
        job: u64,
    },
    /// Job `job` failed.
    Failed {
        /// The job.
        job: u64,
        /// The error message.
        message: String,
    },
}

/// Handle to the worker thread, owned by the UI.
pub struct Worker<P: Clone + Send + 'static> {
    tx: Sender<Command<P>>,
    events: Receiver<WorkerEvent>,
    running: Arc<Mutex<Option<CancelToken>>>,
    next_job: u64,
    thread: Option<JoinHandle<()>>,
}

impl<P: Clone + Send + 'static> Worker<P> {
    /// Start the worker thread running `engine`; `notify` is called after every event (e.g. to
    /// wake the UI).
    pub fn spawn<E: Engine<Params = P>>(engine: E, notify: impl Fn() + Send + 'static) -> Self {
        let (tx, rx) = unbounded::<Command<P>>();
        let (etx, events) = unbounded();
        let running = Arc::new(Mutex::new(None));
        let run2 = running.clone();
        let thread = std::thread::Builder::new()
            .name("meshmatch-worker".into())
            .spawn(move || {
                crate::work::lower_thread_priority();
                worker_loop(engine, rx, etx, run2, notify)
            })
            .expect("spawn worker thread");
        Worker {
            tx,
            events,
            running,
            next_job: 1,
            thread: Some(thread),
        }
    }

    fn cancel_running(&self) {
        if let Some(tok) = self
            .running
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .as_ref()
        {
            tok.cancel();
        }
    }

    /// Send a command; any running job is cancelled first.
    pub fn send(&self, cmd: Command<P>) {
        self.cancel_running();
        let _ = self.tx.send(cmd);
    }

    /// Start a transfer (cancelling the running one) and return its job number.
    pub fn start(&mut self, corr: Vec<Correspondence>, params: P) -> u64 {
        let job = self.next_job;
        self.next_job += 1;
        self.send(Command::StartTransfer { job, corr, params });
        job
    }

    /// Cancel the running job (returns at once; the worker reports `Cancelled`).
    pub fn cancel(&self) {
        self.send(Command::Cancel);
    }

    /// Every event received so far (never blocks).
    pub fn poll(&self) -> Vec<WorkerEvent> {
        self.events.try_iter().collect()
    }

    /// Wait up to `timeout` for the next event (for tests and the CLI).
    pub fn recv_timeout(&self, timeout: std::time::Duration) -> Option<WorkerEvent> {
        self.events.recv_timeout(timeout).ok()
    }
}

impl<P: Clone + Send + 'static> Drop for Worker<P> {
    fn drop(&mut self) {
        self.cancel_running();
        let _ = self.tx.send(Command::Shutdown);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

struct MeshEntry {
    id: u64,
    mesh: Arc<TriMesh>,
}

fn worker_loop<E: Engine>(
    engine: E,
    rx: Receiver<Command<E::Params>>,
    etx: Sender<WorkerEvent>,
    running: Arc<Mutex<Option<CancelToken>>>,
    notify: impl Fn() + Send + 'static,
) {
    let notify = Arc::new(notify);
    let emit = |ev: WorkerEvent| {
        let _ = etx.send(ev);
        notify();
    };
    let mut meshes: HashMap<Side, MeshEntry> = HashMap::new();
    // Prepared meshes keyed by (mesh id, preparation key).
    let mut cache: HashMap<(u64, String), E::Prepared> = HashMap::new();
    let mut pending: std::collections::VecDeque<Command<E::Params>> = Default::default();
    loop {
        let cmd = match pending.pop_front() {
            Some(c) => c,
            None => match rx.recv() {
                Ok(c) => c,
                Err(_) => return,
            },
        };
        match cmd {
            Command::Shutdown => return,
            Command::Cancel => {}
            Command::SetSource(id, mesh) => {
                meshes.insert(Side::Source, MeshEntry { id, mesh });
            }
            Command::SetTarget(id, mesh) => {
                meshes.insert(Side::Target, MeshEntry { id, mesh });
            }
            Command::StartTransfer { job, corr, params } => {
                // Publish the token first, so a command sent from now on cancels this job.
                let token = CancelToken::new();
                *running.lock().unwrap_or_else(|e| e.into_inner()) = Some(token.clone());
                // Coalesce: a newer start or a cancel already queued supersedes this job.
                pending.extend(rx.try_iter());
                if pending
                    .iter()
                    .any(|c| matches!(c, Command::StartTransfer { .. } | Command::Cancel))
                {
                    *running.lock().unwrap_or_else(|e| e.into_inner()) = None;
                    emit(WorkerEvent::Cancelled { job });
                    continue;
                }
                let clock = Instant::now();
                let res = run_job(
                    &engine, job, &corr, &params, &meshes, &mut cache, &token, &etx, &*notify,
                );
                *running.lock().unwrap_or_else(|e| e.into_inner()) = None;
                match res {
                    Ok(solved) => emit(WorkerEvent::Done {
                        job,
                        result: Arc::new(solved),
                        elapsed: clock.elapsed().as_secs_f64(),
                    }),
                    Err(Error::Cancelled) => emit(WorkerEvent::Cancelled { job }),
                    Err(e) => emit(WorkerEvent::Failed {
                        job,
                        message: e.to_string(),
                    }),
                }
                // Forget prepared meshes of replaced meshes.
                let live: Vec<u64> = meshes.values().map(|m| m.id).collect();
                cache.retain(|(id, _), _| live.contains(id));
            }
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn run_job<E: Engine>(
    engine: &E,
    job: u64,
    corr: &[Correspondence],
    params: &E::Params,
    meshes: &HashMap<Side, MeshEntry>,
    cache: &mut HashMap<(u64, String), E::Prepared>,
    cancel: &CancelToken,
    etx: &Sender<WorkerEvent>,
    notify: &dyn Fn(),
) -> Result<Solved> {
    let sink = |event: Event| {
        let _ = etx.send(WorkerEvent::Job { job, event });
        notify();
    };
    let key = engine.prepare_key(params);
    let entry = |side: Side| {
        meshes
            .get(&side)
            .ok_or_else(|| Error::InvalidInput(format!("no {side:?} mesh loaded").to_lowercase()))
    };
    let (source, target) = (entry(Side::Source)?, entry(Side::Target)?);
    let missing = |e: &MeshEntry| !cache.contains_key(&(e.id, key.clone()));
    let (need_s, need_t) = (missing(source), missing(target));
    cancel.check()?;
    let mut prepared = Vec::new();
    if need_s && need_t {
        // A first transfer: both prepared together, each one's sequential stages overlapping
        // the other's.
        let (s, t) = engine.prepare_pair(&source.mesh, &target.mesh, params, &sink, cancel)?;
        prepared = vec![(Side::Source, source, s), (Side::Target, target, t)];
    } else {
        for (side, entry, need) in [
            (Side::Source, source, need_s),
            (Side::Target, target, need_t),
        ] {
            if need {
                prepared.push((
                    side,
                    entry,
                    engine.prepare(&entry.mesh, params, &sink, cancel)?,
                ));
            }
        }
    }
    for (side, entry, prepared) in prepared {
        let (working, working_to_file, file_to_working) = engine.working(&prepared);
        let _ = etx.send(WorkerEvent::Prepared {
            side,
            mesh_id: entry.id,
            working,
            working_to_file,
            file_to_working,
        });
        notify();
        cache.insert((entry.id, key.clone()), prepared);
    }
    let s = &cache[&(meshes[&Side::Source].id, key.clone())];
    let t = &cache[&(meshes[&Side::Target].id, key)];
    cancel.check()?;
    let mut solved = engine.solve(s, t, corr, params, &sink, cancel)?;
    cancel.check()?;
    solved.texture = view_texture(&target.mesh, &solved);
    Ok(solved)
}
