//! File dialogs: the system's (rfd, on its own thread so the UI keeps drawing while one is
//! open), or an in-app typed-path dialog when the desktop has none. No system dialog is
//! assumed when neither a desktop portal (a D-Bus session) nor zenity exists, or when one
//! returned at once without showing anything; from then on the in-app one is used.

use std::path::PathBuf;
use std::sync::mpsc::{channel, Receiver, Sender};
use std::time::{Duration, Instant};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Purpose {
    OpenModel,
    OpenProject,
    SaveProject,
    Export,
    InitFile,
    KeyFile,
}

impl Purpose {
    pub fn title(self) -> &'static str {
        match self {
            Purpose::OpenModel => "Open a model folder",
            Purpose::OpenProject => "Open a project",
            Purpose::SaveProject => "Save the project",
            Purpose::Export => "Export the take",
            Purpose::InitFile => "Initial pose from a motion file",
            Purpose::KeyFile => "Key from a motion file",
        }
    }
}

/// How a dialog ended.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Outcome {
    Chosen(PathBuf),
    Cancelled,
    /// No system dialog could be shown.
    Unavailable,
}

/// A system dialog that returns sooner than this showed nothing (nobody answers one that fast).
const INSTANT: Duration = Duration::from_millis(250);

/// The in-app typed-path dialog.
pub struct PathPrompt {
    pub purpose: Purpose,
    pub text: String,
    focus: bool,
}

pub struct Dialogs {
    tx: Sender<(Purpose, Outcome)>,
    rx: Receiver<(Purpose, Outcome)>,
    open: bool,
    /// Whether a system dialog may be tried.
    system: bool,
    pub prompt: Option<PathPrompt>,
}

/// Whether this desktop can show a system file dialog (rfd's portal, or its zenity fallback).
pub fn system_dialog_available() -> bool {
    let portal = std::env::var_os("DBUS_SESSION_BUS_ADDRESS").is_some_and(|v| !v.is_empty());
    let zenity = std::env::var_os("PATH").is_some_and(|p| std::env::split_paths(&p).any(|d| d.join("zenity").is_file()));
    portal || zenity
}

impl Dialogs {
    pub fn new(system: bool) -> Self {
        let (tx, rx) = channel();
        Self { tx, rx, open: false, system, prompt: None }
    }

    pub fn is_open(&self) -> bool {
        self.open || self.prompt.is_some()
    }

    /// Opens a dialog; false when no system dialog is available (the caller then opens the
    /// in-app one with [`Dialogs::prompt`]).
    pub fn open(&mut self, purpose: Purpose, ctx: &egui::Context, suggested: Option<PathBuf>) -> bool {
        if self.open {
            return true;
        }
        if !self.system {
            return false;
        }
        self.open = true;
        let (tx, ctx) = (self.tx.clone(), ctx.clone());
        let spawned = std::thread::Builder::new().name("glocal-dialog".into()).spawn(move || {
            let mut d = rfd::FileDialog::new().set_title(purpose.title());
            if let Some(s) = &suggested {
                if let Some(dir) = s.parent().filter(|p| p.is_dir()) {
                    d = d.set_directory(dir);
                }
                if let Some(name) = s.file_name() {
                    d = d.set_file_name(name.to_string_lossy());
                }
            }
            let start = Instant::now();
            let path = match purpose {
                Purpose::OpenModel => d.pick_folder(),
                Purpose::OpenProject => d.add_filter("Glocal project", &["json"]).pick_file(),
                Purpose::SaveProject => d.add_filter("Glocal project", &["json"]).save_file(),
                Purpose::Export => d.add_filter("Motion", &["bvh", "json", "npy"]).save_file(),
                Purpose::InitFile | Purpose::KeyFile => d.add_filter("Motion", &["bvh", "npy", "txt"]).pick_file(),
            };
            let outcome = match path {
                Some(p) => Outcome::Chosen(p),
                None if start.elapsed() < INSTANT => Outcome::Unavailable,
                None => Outcome::Cancelled,
            };
            let _ = tx.send((purpose, outcome));
            ctx.request_repaint();
        });
        if spawned.is_err() {
            self.open = false;
            return false;
        }
        true
    }

    /// Opens the in-app dialog, starting from `suggested`; system dialogs are not tried again.
    pub fn prompt(&mut self, purpose: Purpose, suggested: Option<PathBuf>) {
        self.system = false;
        let text = suggested.map(|p| p.display().to_string()).unwrap_or_default();
        self.prompt = Some(PathPrompt { purpose, text, focus: true });
    }

    /// System dialogs that closed.
    pub fn poll(&mut self) -> Vec<(Purpose, Outcome)> {
        let done: Vec<_> = self.rx.try_iter().collect();
        if !done.is_empty() {
            self.open = false;
        }
        done
    }

    /// Draws the in-app dialog; returns its outcome when it closes.
    pub fn prompt_ui(&mut self, ctx: &egui::Context) -> Option<(Purpose, Outcome)> {
        let prompt = self.prompt.as_mut()?;
        let mut outcome = None;
        egui::Window::new(prompt.purpose.title()).collapsible(false).resizable(false).anchor(egui::Align2::CENTER_CENTER, egui::vec2(0.0, 0.0)).show(ctx, |ui| {
            ui.label("No system file dialog is available here: type the path.");
            let label = ui.label("Path");
            let edit = ui.add(egui::TextEdit::singleline(&mut prompt.text).desired_width(420.0)).labelled_by(label.id);
            if std::mem::take(&mut prompt.focus) {
                edit.request_focus();
            }
            let enter = edit.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
            ui.horizontal(|ui| {
                if ui.button("OK").clicked() || enter {
                    let path = PathBuf::from(prompt.text.trim());
                    outcome = Some(if path.as_os_str().is_empty() { Outcome::Cancelled } else { Outcome::Chosen(path) });
                }
                if ui.button("Cancel").clicked() || ui.input(|i| i.key_pressed(egui::Key::Escape)) {
                    outcome = Some(Outcome::Cancelled);
                }
            });
        });
        let purpose = prompt.purpose;
        outcome.map(|o| {
            self.prompt = None;
            (purpose, o)
        })
    }
}
