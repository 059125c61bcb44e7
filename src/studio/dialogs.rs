//! Native file dialogs (rfd) on their own thread, so the UI keeps drawing while one is
//! open. Every dialog has a typed-path alternative in the UI, since a desktop may have
//! none.

use std::path::PathBuf;
use std::sync::mpsc::{channel, Receiver, Sender};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Purpose {
    OpenModel,
    OpenProject,
    SaveProject,
    Export,
    InitFile,
}

pub struct Dialogs {
    tx: Sender<(Purpose, Option<PathBuf>)>,
    rx: Receiver<(Purpose, Option<PathBuf>)>,
    open: bool,
}

impl Default for Dialogs {
    fn default() -> Self {
        let (tx, rx) = channel();
        Self { tx, rx, open: false }
    }
}

impl Dialogs {
    pub fn is_open(&self) -> bool {
        self.open
    }

    pub fn open(&mut self, purpose: Purpose, ctx: &egui::Context, suggested: Option<PathBuf>) {
        if self.open {
            return;
        }
        self.open = true;
        let (tx, ctx) = (self.tx.clone(), ctx.clone());
        let spawned = std::thread::Builder::new().name("glocal-dialog".into()).spawn(move || {
            let mut d = rfd::FileDialog::new();
            if let Some(s) = &suggested {
                if let Some(dir) = s.parent().filter(|p| p.is_dir()) {
                    d = d.set_directory(dir);
                }
                if let Some(name) = s.file_name() {
                    d = d.set_file_name(name.to_string_lossy());
                }
            }
            let path = match purpose {
                Purpose::OpenModel => d.set_title("Open a model folder").pick_folder(),
                Purpose::OpenProject => d.set_title("Open a project").add_filter("Glocal project", &["json"]).pick_file(),
                Purpose::SaveProject => d.set_title("Save the project").add_filter("Glocal project", &["json"]).save_file(),
                Purpose::Export => d.set_title("Export the take").add_filter("Motion", &["bvh", "json", "npy"]).save_file(),
                Purpose::InitFile => d.set_title("Initial pose from a motion file").add_filter("Motion", &["bvh", "npy", "txt"]).pick_file(),
            };
            let _ = tx.send((purpose, path));
            ctx.request_repaint();
        });
        if spawned.is_err() {
            self.open = false;
        }
    }

    /// Dialogs that closed, with the chosen path (None: cancelled or unavailable).
    pub fn poll(&mut self) -> Vec<(Purpose, Option<PathBuf>)> {
        let done: Vec<_> = self.rx.try_iter().collect();
        if !done.is_empty() {
            self.open = false;
        }
        done
    }
}
