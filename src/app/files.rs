//! File dialogs: the system's (rfd) where it can work, else a built-in egui file browser.
//!
//! On Linux rfd talks to the desktop portal over the D-Bus session bus. Without one (a bare Xvfb,
//! an X-forwarded session) the portal call fails and looks exactly like a cancel: the menu item
//! would do nothing. There the app shows its own browser instead. Either way a request ends in
//! a [`FileAction`] and a path that the app takes with [`FileDialogs::take`].

use std::path::{Path, PathBuf};

use eframe::egui;

use crate::correspondence::Side;

/// What a chosen file is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileAction {
    /// Open a mesh into a view.
    OpenMesh(Side),
    /// Open an image as the source's texture.
    OpenTexture,
    /// Open a correspondences JSON.
    OpenCorrespondences,
    /// Save the correspondences JSON.
    SaveCorrespondences,
    /// Export the result (format by extension).
    ExportResult,
    /// Export the working-resolution result as PLY.
    ExportDense,
    /// Export a side's mesh with its paint.
    ExportPainted(Side),
    /// Open a session.
    OpenSession,
    /// Save the session.
    SaveSession,
    /// The input file of system tool `.0` (`app.systems`), as its prompt describes.
    SystemFile(usize, super::systems::FilePrompt),
    /// The output file of system tool `.0`, written by its job (a save dialog).
    SystemSave(usize, super::systems::FilePrompt),
    /// The edited geometry for Tools > Update texture for new geometry.
    EditedGeometry,
}

impl FileAction {
    /// Dialog title.
    pub fn title(self) -> String {
        match self {
            FileAction::OpenMesh(s) => format!("Open {} mesh", side_name(s)),
            FileAction::OpenTexture => "Open source texture".into(),
            FileAction::OpenCorrespondences => "Open correspondences".into(),
            FileAction::SaveCorrespondences => "Save correspondences".into(),
            FileAction::ExportResult => "Export result".into(),
            FileAction::ExportDense => "Export dense result".into(),
            FileAction::ExportPainted(s) => format!("Export painted {} mesh", side_name(s)),
            FileAction::OpenSession => "Open session".into(),
            FileAction::SaveSession => "Save session".into(),
            FileAction::SystemFile(_, p) | FileAction::SystemSave(_, p) => p.0.into(),
            FileAction::EditedGeometry => "Open the edited geometry".into(),
        }
    }

    /// Whether the file is written (a save dialog) rather than read.
    pub fn saves(self) -> bool {
        matches!(
            self,
            FileAction::SaveCorrespondences
                | FileAction::ExportResult
                | FileAction::ExportDense
                | FileAction::ExportPainted(_)
                | FileAction::SaveSession
                | FileAction::SystemSave(..)
        )
    }

    /// The filter's name and extensions.
    pub fn filter(self) -> (&'static str, &'static [&'static str]) {
        match self {
            FileAction::OpenMesh(_) | FileAction::EditedGeometry => {
                ("meshes", &["obj", "ply", "gltf", "glb"])
            }
            FileAction::OpenTexture => ("images", &["png", "jpg", "jpeg"]),
            FileAction::SystemFile(_, p) | FileAction::SystemSave(_, p) => (p.1, p.2),
            FileAction::OpenCorrespondences | FileAction::SaveCorrespondences => {
                ("correspondences", &["json"])
            }
            FileAction::OpenSession | FileAction::SaveSession => ("session", &["json"]),
            FileAction::ExportResult | FileAction::ExportPainted(_) => {
                ("mesh", &["ply", "glb", "gltf", "obj"])
            }
            FileAction::ExportDense => ("ply", &["ply"]),
        }
    }
}

fn side_name(s: Side) -> &'static str {
    match s {
        Side::Source => "source",
        Side::Target => "target",
    }
}

/// Whether the system dialog can work here: `MESHMATCH_FILE_DIALOG=builtin|native` decides;
/// otherwise on Linux it needs a D-Bus session bus (the portal), elsewhere it always can.
pub fn native_dialogs_available() -> bool {
    match std::env::var("MESHMATCH_FILE_DIALOG").as_deref() {
        Ok("builtin") => return false,
        Ok("native") => return true,
        _ => {}
    }
    if !cfg!(target_os = "linux") {
        return true;
    }
    if std::env::var_os("DBUS_SESSION_BUS_ADDRESS").is_some() {
        return true;
    }
    // The systemd user bus, used when the variable is not exported.
    std::env::var_os("XDG_RUNTIME_DIR")
        .map(|d| Path::new(&d).join("bus").exists())
        .unwrap_or(false)
}

/// The built-in browser's state.
#[derive(Clone, Debug)]
struct Browser {
    action: FileAction,
    dir: PathBuf,
    /// The directory field as typed.
    dir_text: String,
    /// The file name field.
    name: String,
    /// The last error (unreadable directory, missing file).
    error: String,
}

/// The app's file dialogs: the system's or the built-in browser.
#[derive(Debug)]
pub struct FileDialogs {
    /// Use the system dialog (rfd); else the built-in browser.
    pub native: bool,
    browser: Option<Browser>,
    done: Option<(FileAction, PathBuf)>,
    /// Directory of the last chosen file (where the next browser starts).
    last_dir: Option<PathBuf>,
}

impl Default for FileDialogs {
    fn default() -> Self {
        FileDialogs {
            native: native_dialogs_available(),
            browser: None,
            done: None,
            last_dir: None,
        }
    }
}

impl FileDialogs {
    /// Ask for a file for `action`: the system dialog answers at once; the built-in browser opens
    /// and answers in a later frame.
    pub fn request(&mut self, action: FileAction) {
        if self.native {
            let (name, exts) = action.filter();
            let mut dlg = rfd::FileDialog::new()
                .set_title(action.title())
                .add_filter(name, exts);
            if let Some(d) = &self.last_dir {
                dlg = dlg.set_directory(d);
            }
            let picked = if action.saves() {
                dlg.save_file()
            } else {
                dlg.pick_file()
            };
            if let Some(p) = picked {
                self.finish(action, p);
            }
            return;
        }
        let dir = self
            .last_dir
            .clone()
            .or_else(|| std::env::current_dir().ok())
            .unwrap_or_else(|| PathBuf::from("/"));
        self.browser = Some(Browser {
            action,
            dir_text: dir.display().to_string(),
            dir,
            name: String::new(),
            error: String::new(),
        });
    }

    /// The chosen file, once: the action it was asked for and its path.
    pub fn take(&mut self) -> Option<(FileAction, PathBuf)> {
        self.done.take()
    }

    /// The built-in browser is open.
    pub fn browsing(&self) -> bool {
        self.browser.is_some()
    }

    fn finish(&mut self, action: FileAction, path: PathBuf) {
        self.last_dir = path.parent().map(Path::to_path_buf);
        self.done = Some((action, path));
    }

    /// Show the built-in browser if it is open.
    pub fn show(&mut self, ctx: &egui::Context) {
        let Some(mut b) = self.browser.take() else {
            return;
        };
        let (filter_name, exts) = b.action.filter();
        let mut open = true;
        let mut chosen: Option<PathBuf> = None;
        let mut cancel = false;
        egui::Window::new(b.action.title())
            .open(&mut open)
            .collapsible(false)
            .default_size([520.0, 420.0])
            .show(ctx, |ui| {
                ui.horizontal(|ui| {
                    ui.label("Folder");
                    let r =
                        ui.add(egui::TextEdit::singleline(&mut b.dir_text).desired_width(360.0));
                    if r.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter)) {
                        let p = PathBuf::from(b.dir_text.trim());
                        if p.is_dir() {
                            b.dir = p;
                            b.error.clear();
                        } else {
                            b.error = format!("{} is not a folder", p.display());
                        }
                    }
                    if ui.button("Up").clicked()
                        && let Some(parent) = b.dir.parent()
                    {
                        b.dir = parent.to_path_buf();
                        b.dir_text = b.dir.display().to_string();
                    }
                });
                let (dirs, files) = list_dir(&b.dir, exts);
                egui::ScrollArea::vertical()
                    .max_height(260.0)
                    .auto_shrink([false, false])
                    .show(ui, |ui| {
                        if let Err(e) = &files {
                            ui.colored_label(egui::Color32::LIGHT_RED, e);
                        }
                        for d in &dirs {
                            if ui
                                .selectable_label(false, format!("[{d}]"))
                                .on_hover_text("Open this folder")
                                .clicked()
                            {
                                b.dir = b.dir.join(d);
                                b.dir_text = b.dir.display().to_string();
                            }
                        }
                        for f in files.iter().flatten() {
                            let r = ui.selectable_label(b.name == *f, f);
                            if r.clicked() {
                                b.name = f.clone();
                            }
                            if r.double_clicked() {
                                chosen = Some(b.dir.join(f));
                            }
                        }
                    });
                ui.horizontal(|ui| {
                    ui.label("File");
                    ui.add(egui::TextEdit::singleline(&mut b.name).desired_width(300.0));
                    ui.label(format!("{filter_name}: {}", exts.join(", ")));
                });
                if !b.error.is_empty() {
                    ui.colored_label(egui::Color32::LIGHT_RED, &b.error);
                }
                ui.horizontal(|ui| {
                    let verb = if b.action.saves() { "Save" } else { "Open" };
                    if ui.button(verb).clicked() {
                        let name = b.name.trim();
                        // A typed absolute path is taken as it is.
                        let p = if Path::new(name).is_absolute() {
                            PathBuf::from(name)
                        } else {
                            b.dir.join(name)
                        };
                        if name.is_empty() {
                            b.error = "choose or type a file name".into();
                        } else if !b.action.saves() && !p.is_file() {
                            b.error = format!("{} does not exist", p.display());
                        } else {
                            chosen = Some(p);
                        }
                    }
                    if ui.button("Cancel").clicked() {
                        cancel = true;
                    }
                });
            });
        if let Some(p) = chosen {
            self.finish(b.action, p);
        } else if open && !cancel {
            self.browser = Some(b);
        }
    }
}

/// Sub-folders and the files with one of `exts` (case-insensitive) in `dir`, sorted; hidden
/// entries are left out.
fn list_dir(dir: &Path, exts: &[&str]) -> (Vec<String>, std::result::Result<Vec<String>, String>) {
    let rd = match std::fs::read_dir(dir) {
        Ok(rd) => rd,
        Err(e) => return (Vec::new(), Err(format!("{}: {e}", dir.display()))),
    };
    let (mut dirs, mut files) = (Vec::new(), Vec::new());
    for e in rd.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') {
            continue;
        }
        let path = e.path();
        if path.is_dir() {
            dirs.push(name);
        } else if path
            .extension()
            .and_then(|x| x.to_str())
            .is_some_and(|x| exts.iter().any(|e| e.eq_ignore_ascii_case(x)))
        {
            files.push(name);
        }
    }
    dirs.sort();
    files.sort();
    (dirs, Ok(files))
}
