//! Autosave and crash recovery.
//!
//! Each running app owns a folder `<data>/autosave/<pid>-<start ms>/` holding a `lock` file it
//! keeps locked (an OS file lock, released by the system however the process ends) and, while
//! there is unsaved work, the latest autosave: a session `s<N>.json` with its sidecars
//! `s<N>.*.ply|glb`, written sidecars first and the JSON last by a rename, so the newest JSON is
//! always complete; older generations are removed after it. A clean exit removes the folder;
//! saving the work removes the autosave (the user's file holds it).
//!
//! At start, a folder whose lock nobody holds belongs to an app that was killed or crashed: its
//! newest session is offered for recovery (Recover / Discard).
//!
//! `<data>` is `$MESHMATCH_DATA_DIR` when set, else the user's data folder:
//! `$XDG_DATA_HOME/meshmatch` or `~/.local/share/meshmatch` (Linux), `%LOCALAPPDATA%\meshmatch`
//! (Windows), `~/Library/Application Support/meshmatch` (macOS).

use std::fs::File;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime};

use crate::error::{Error, Result};

use super::state::{AppParams, AppState};

/// Environment variable that overrides the data folder (tests, portable installs).
pub const DATA_DIR_ENV: &str = "MESHMATCH_DATA_DIR";
/// Environment variable that sets the autosave period in seconds (default [`DEFAULT_PERIOD`]).
pub const PERIOD_ENV: &str = "MESHMATCH_AUTOSAVE_SECS";
/// Time between autosaves while there are unsaved changes.
pub const DEFAULT_PERIOD: Duration = Duration::from_secs(60);

/// The user's data folder for meshmatch (see the module's documentation).
pub fn data_dir() -> Option<PathBuf> {
    let env = |k: &str| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    if let Some(d) = env(DATA_DIR_ENV) {
        return Some(d);
    }
    let base = if cfg!(windows) {
        env("LOCALAPPDATA").or_else(|| env("APPDATA"))
    } else if cfg!(target_os = "macos") {
        env("HOME").map(|h| h.join("Library").join("Application Support"))
    } else {
        env("XDG_DATA_HOME").or_else(|| env("HOME").map(|h| h.join(".local").join("share")))
    }?;
    Some(base.join("meshmatch"))
}

/// The autosave period: `$MESHMATCH_AUTOSAVE_SECS` (seconds, may be fractional) or the default.
pub fn period_from_env() -> Duration {
    std::env::var(PERIOD_ENV)
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s >= 0.0)
        .map_or(DEFAULT_PERIOD, Duration::from_secs_f64)
}

/// This app's autosave folder, locked while the app runs.
#[derive(Debug)]
pub struct Autosave {
    dir: PathBuf,
    /// Held for the life of the app: its lock tells other instances this folder is alive.
    _lock: File,
    period: Duration,
    generation: u64,
    /// `AppState::edits` at the last autosave (`None`: nothing written).
    written: Option<u64>,
    last: Instant,
    /// The last autosave's error, shown once in the status line.
    pub error: Option<String>,
}

/// A killed app's autosave, locked by this app while it decides.
#[derive(Debug)]
pub struct Recovery {
    /// The dead app's folder.
    pub dir: PathBuf,
    /// Its newest complete session.
    pub session: PathBuf,
    /// When that session was written.
    pub modified: SystemTime,
    _lock: File,
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> Error + '_ {
    move |e| Error::io(path, e)
}

/// The newest complete session `s<N>.json` in `dir`, with its generation.
fn newest_session(dir: &Path) -> Option<(u64, PathBuf)> {
    std::fs::read_dir(dir)
        .ok()?
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().into_string().ok()?;
            let n = name
                .strip_prefix('s')?
                .strip_suffix(".json")?
                .parse()
                .ok()?;
            Some((n, e.path()))
        })
        .max_by_key(|(n, _)| *n)
}

/// Remove generations older than `keep` (all when `None`): their JSON first, so a JSON never
/// outlives its sidecars.
fn remove_generations(dir: &Path, keep: Option<u64>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut files: Vec<(u64, bool, PathBuf)> = entries
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().into_string().ok()?;
            let rest = name.strip_prefix('s')?;
            let (n, tail) = rest.split_once('.')?;
            let n: u64 = n.parse().ok()?;
            Some((n, tail == "json", e.path()))
        })
        .filter(|(n, _, _)| keep.is_none_or(|k| *n < k))
        .collect();
    // JSONs first
    files.sort_by_key(|(n, json, _)| (!*json, *n));
    for (_, _, p) in files {
        let _ = std::fs::remove_file(p);
    }
}

impl Autosave {
    /// Create this app's folder under `<root>/autosave/` and lock it.
    pub fn start(root: &Path, period: Duration) -> Result<Self> {
        let millis = SystemTime::now()
            .duration_since(SystemTime::UNIX_EPOCH)
            .map_or(0, |d| d.as_millis());
        let dir = root
            .join("autosave")
            .join(format!("{}-{millis}", std::process::id()));
        std::fs::create_dir_all(&dir).map_err(io(&dir))?;
        let lock_path = dir.join("lock");
        let lock = File::create(&lock_path).map_err(io(&lock_path))?;
        lock.try_lock().map_err(|e| {
            Error::InvalidInput(format!("{}: cannot lock: {e}", lock_path.display()))
        })?;
        Ok(Autosave {
            dir,
            _lock: lock,
            period,
            generation: 0,
            written: None,
            last: Instant::now(),
            error: None,
        })
    }

    /// This app's autosave folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The newest autosaved session, if one is on disk.
    pub fn latest(&self) -> Option<PathBuf> {
        newest_session(&self.dir).map(|(_, p)| p)
    }

    /// How long until an autosave is due for `state` (`None`: nothing to save: no unsaved
    /// change since the last autosave).
    pub fn due_in<P: AppParams>(&self, state: &AppState<P>, now: Instant) -> Option<Duration> {
        if !state.is_dirty() || self.written == Some(state.edits()) {
            return None;
        }
        Some((self.last + self.period).saturating_duration_since(now))
    }

    /// Keep the autosave in step with `state` (call every frame): write it when there are
    /// changes it does not hold and the period has passed since the last write; drop it once
    /// the work is saved. Returns the session written, if any.
    pub fn tick<P: AppParams>(&mut self, state: &AppState<P>, now: Instant) -> Option<PathBuf> {
        if !state.is_dirty() {
            if self.written.is_some() {
                remove_generations(&self.dir, None);
                self.written = None;
            }
            return None;
        }
        if self.due_in(state, now)? > Duration::ZERO {
            return None;
        }
        self.last = now;
        match self.write(state) {
            Ok(p) => Some(p),
            Err(e) => {
                // retried at the next period
                self.error = Some(format!("autosave failed: {e}"));
                None
            }
        }
    }

    /// Write the session now (a new generation), then remove the older ones.
    pub fn write<P: AppParams>(&mut self, state: &AppState<P>) -> Result<PathBuf> {
        self.generation += 1;
        let path = self.dir.join(format!("s{}.json", self.generation));
        if let Err(e) = state.save_session(&path) {
            // remove this generation's sidecars; the previous complete one stays
            let prefix = format!("s{}.", self.generation);
            for f in std::fs::read_dir(&self.dir).into_iter().flatten().flatten() {
                if f.file_name().to_string_lossy().starts_with(&prefix) {
                    let _ = std::fs::remove_file(f.path());
                }
            }
            return Err(e);
        }
        remove_generations(&self.dir, Some(self.generation));
        self.written = Some(state.edits());
        Ok(path)
    }

    /// A clean exit: remove the folder (its lock goes with the app).
    pub fn finish(self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Autosaves left by apps that ended without a clean exit under `<root>/autosave/`, newest
/// first, each locked by this app. Folders of ended apps with nothing to recover are removed;
/// folders of apps still running are left alone.
pub fn orphans(root: &Path) -> Vec<Recovery> {
    let base = root.join("autosave");
    let Ok(entries) = std::fs::read_dir(&base) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for e in entries.flatten() {
        let dir = e.path();
        if !dir.is_dir() {
            continue;
        }
        let lock_path = dir.join("lock");
        let Ok(lock) = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&lock_path)
        else {
            // no lock file: a folder being created this instant, or not ours
            continue;
        };
        if lock.try_lock().is_err() {
            // its app is running (or another app is deciding about it)
            continue;
        }
        match newest_session(&dir) {
            Some((_, session)) => {
                let modified = std::fs::metadata(&session)
                    .and_then(|m| m.modified())
                    .unwrap_or(SystemTime::UNIX_EPOCH);
                out.push(Recovery {
                    dir,
                    session,
                    modified,
                    _lock: lock,
                });
            }
            None => {
                drop(lock);
                let _ = std::fs::remove_dir_all(&dir);
            }
        }
    }
    out.sort_by_key(|r| std::cmp::Reverse(r.modified));
    out
}

impl Recovery {
    /// Restore this autosave into `state` (as unsaved work: no file holds it yet). Meshes that
    /// were computed come back as computed. The folder stays until [`Recovery::discard`].
    pub fn restore<P: AppParams>(&self, state: &mut AppState<P>) -> Result<()> {
        state.load_session(&self.session)?;
        state.forget_files_under(&self.dir);
        state.mark_changed();
        state.mark_unsaved();
        Ok(())
    }

    /// How old the autosave is, in words ("3 min ago").
    pub fn age(&self) -> String {
        let s = SystemTime::now()
            .duration_since(self.modified)
            .map_or(0, |d| d.as_secs());
        match s {
            0..=59 => format!("{s} s ago"),
            60..=7199 => format!("{} min ago", s / 60),
            _ => format!("{} h ago", s / 3600),
        }
    }

    /// Remove the dead app's folder.
    pub fn discard(self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}
