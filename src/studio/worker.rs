//! The background worker: owns the model, loads it, generates takes, builds the seed map
//! and writes exports, so the UI thread never waits. The UI sends [`Request`]s; the worker
//! answers with [`Reply`]s and wakes the UI with `request_repaint`.
//!
//! Cancelling: every generation has an id and the handle keeps the id of the one the UI
//! still wants. The progress callback stops a generation as soon as it is no longer
//! wanted (a newer edit, or the Cancel button), and queued requests that are no longer
//! wanted are skipped.

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{channel, Receiver, Sender, TryRecvError};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context as _, Result};

use super::tsne;
use crate::model::glocal::GlocalModel;
use crate::model::spec::ModelSpec;
use crate::motion::Motion;
use crate::synth::export::export;
use crate::synth::init::initial_features;
use crate::synth::render::class_color;
use crate::synth::{generate, GenerateOptions, InitPose, SegmentSpan};

/// What the UI knows of a loaded model.
pub struct ModelInfo {
    pub dir: PathBuf,
    pub spec: ModelSpec,
    pub seeds: Vec<SeedInfo>,
    pub has_locgen: bool,
}

#[derive(Clone, Debug)]
pub struct SeedInfo {
    pub class: usize,
    pub clip: String,
    pub frame: usize,
}

/// The seed bank in 2D.
pub struct SeedMap {
    pub model_dir: PathBuf,
    /// Map position of each seed (same order as [`ModelInfo::seeds`]).
    pub points: Vec<[f32; 2]>,
}

/// A generated take, ready to show.
pub struct Take {
    pub id: u64,
    pub motion: Arc<Motion>,
    pub segments: Vec<SegmentSpan>,
    /// Class colour of every frame.
    pub frame_colors: Arc<Vec<[u8; 3]>>,
    pub block_classes: Vec<usize>,
    /// Each block's place in the seed map (empty until the map exists).
    pub path: Vec<[f32; 2]>,
    pub options: GenerateOptions,
    pub millis: f64,
}

pub enum Request {
    LoadModel(PathBuf),
    Generate { id: u64, options: GenerateOptions },
    /// Checks that an initial pose can start a take on the current model.
    CheckInit(InitPose),
    Export { motion: Arc<Motion>, segments: Vec<SegmentSpan>, path: PathBuf },
}

pub enum Reply {
    ModelLoaded(Arc<ModelInfo>),
    ModelFailed { dir: PathBuf, error: String },
    Map(Arc<SeedMap>),
    MapFailed(String),
    Progress { id: u64, fraction: f32 },
    Generated(Arc<Take>),
    GenerateFailed { id: u64, error: String, cancelled: bool },
    /// The map path of a take generated before the map existed.
    Path { id: u64, path: Vec<[f32; 2]> },
    InitOk(InitPose),
    InitFailed { init: InitPose, error: String },
    Exported(PathBuf),
    ExportFailed { path: PathBuf, error: String },
}

/// The UI's end of the worker.
pub struct Worker {
    tx: Sender<Request>,
    rx: Receiver<Reply>,
    wanted: Arc<AtomicU64>,
    next_id: u64,
}

impl Worker {
    pub fn spawn(ctx: egui::Context) -> Self {
        let (tx, requests) = channel();
        let (replies, rx) = channel();
        let wanted = Arc::new(AtomicU64::new(0));
        let state = WorkerState { ctx, replies, wanted: wanted.clone(), model: None, map: None, last_blocks: None };
        std::thread::Builder::new()
            .name("glocal-worker".into())
            .spawn(move || state.run(&requests))
            .expect("cannot start the worker thread");
        Self { tx, rx, wanted, next_id: 1 }
    }

    pub fn load_model(&self, dir: PathBuf) {
        let _ = self.tx.send(Request::LoadModel(dir));
    }

    /// Starts a generation (cancelling any older one); returns its id.
    pub fn generate(&mut self, options: GenerateOptions) -> u64 {
        let id = self.fresh_id();
        self.wanted.store(id, Ordering::SeqCst);
        let _ = self.tx.send(Request::Generate { id, options });
        id
    }

    /// Stops the generation under way, if any.
    pub fn cancel(&mut self) {
        let id = self.fresh_id();
        self.wanted.store(id, Ordering::SeqCst);
    }

    pub fn check_init(&self, init: InitPose) {
        let _ = self.tx.send(Request::CheckInit(init));
    }

    pub fn export(&self, motion: Arc<Motion>, segments: Vec<SegmentSpan>, path: PathBuf) {
        let _ = self.tx.send(Request::Export { motion, segments, path });
    }

    /// Every reply that has arrived.
    pub fn poll(&self) -> Vec<Reply> {
        self.rx.try_iter().collect()
    }

    fn fresh_id(&mut self) -> u64 {
        self.next_id += 1;
        self.next_id
    }
}

struct WorkerState {
    ctx: egui::Context,
    replies: Sender<Reply>,
    wanted: Arc<AtomicU64>,
    model: Option<GlocalModel>,
    /// Seed embeddings and their map positions, for the current model.
    map: Option<(Vec<Vec<f32>>, Vec<[f32; 2]>)>,
    /// The block embeddings of the last take, kept to place it once the map exists.
    last_blocks: Option<(u64, Vec<Vec<f32>>)>,
}

impl WorkerState {
    fn send(&self, reply: Reply) {
        let _ = self.replies.send(reply);
        self.ctx.request_repaint();
    }

    fn run(mut self, requests: &Receiver<Request>) {
        loop {
            let request = match requests.try_recv() {
                Ok(r) => r,
                Err(TryRecvError::Disconnected) => return,
                Err(TryRecvError::Empty) => {
                    // Idle: build the seed map if the model has none yet, then wait.
                    if self.model.is_some() && self.map.is_none() {
                        self.build_map();
                        continue;
                    }
                    match requests.recv() {
                        Ok(r) => r,
                        Err(_) => return,
                    }
                }
            };
            match request {
                Request::LoadModel(dir) => self.load(dir),
                Request::Generate { id, options } => {
                    if self.wanted.load(Ordering::SeqCst) == id {
                        self.generate(id, &options);
                    }
                }
                Request::CheckInit(init) => {
                    let reply = match self.model.as_ref().context("no model is loaded").and_then(|m| initial_features(m, &init)) {
                        Ok(_) => Reply::InitOk(init),
                        Err(e) => Reply::InitFailed { init, error: format!("{e:#}") },
                    };
                    self.send(reply);
                }
                Request::Export { motion, segments, path } => {
                    let reply = match export(&motion, &segments, &path) {
                        Ok(()) => Reply::Exported(path),
                        Err(e) => Reply::ExportFailed { path, error: format!("{e:#}") },
                    };
                    self.send(reply);
                }
            }
        }
    }

    fn load(&mut self, dir: PathBuf) {
        match GlocalModel::load(&dir) {
            Ok(model) => {
                let info = ModelInfo {
                    dir: dir.clone(),
                    spec: model.spec.clone(),
                    seeds: model.seeds.iter().map(|s| SeedInfo { class: s.class, clip: s.clip.clone(), frame: s.frame }).collect(),
                    has_locgen: model.has_locgen(),
                };
                self.model = Some(model);
                self.map = None;
                self.last_blocks = None;
                self.send(Reply::ModelLoaded(Arc::new(info)));
            }
            // The model in use, if any, stays.
            Err(e) => self.send(Reply::ModelFailed { dir, error: format!("{e:#}") }),
        }
    }

    fn generate(&mut self, id: u64, options: &GenerateOptions) {
        let Some(model) = self.model.as_mut() else {
            self.send(Reply::GenerateFailed { id, error: "no model is loaded".into(), cancelled: false });
            return;
        };
        let start = Instant::now();
        let (wanted, replies, ctx) = (self.wanted.clone(), self.replies.clone(), self.ctx.clone());
        let mut last_sent = 0.0f32;
        let result = generate(model, options, &mut |fraction| {
            if fraction - last_sent >= 0.05 || fraction >= 1.0 {
                last_sent = fraction;
                let _ = replies.send(Reply::Progress { id, fraction });
                ctx.request_repaint();
            }
            wanted.load(Ordering::SeqCst) == id
        });
        match result {
            Ok(g) => {
                let frames = g.motion.frames();
                let mut colors = vec![[128, 128, 128]; frames];
                for s in &g.segments {
                    for c in &mut colors[s.start_frame.min(frames)..s.end_frame.min(frames)] {
                        *c = class_color(s.class);
                    }
                }
                let path = self.map.as_ref().filter(|(emb, _)| !emb.is_empty()).map(|(emb, pts)| tsne::project(&g.block_embeddings, emb, pts, tsne::PROJECT_K)).unwrap_or_default();
                if self.map.is_none() {
                    self.last_blocks = Some((id, g.block_embeddings));
                }
                let take = Take {
                    id,
                    motion: Arc::new(g.motion),
                    segments: g.segments,
                    frame_colors: Arc::new(colors),
                    block_classes: g.block_classes,
                    path,
                    options: options.clone(),
                    millis: start.elapsed().as_secs_f64() * 1e3,
                };
                self.send(Reply::Generated(Arc::new(take)));
            }
            Err(e) => {
                let cancelled = self.wanted.load(Ordering::SeqCst) != id;
                self.send(Reply::GenerateFailed { id, error: format!("{e:#}"), cancelled });
            }
        }
    }

    fn build_map(&mut self) {
        let Some(model) = self.model.as_mut() else { return };
        let model_dir = model.dir.clone();
        let result = seed_embeddings(model).and_then(|emb| {
            let pts = tsne::tsne_2d(&emb, 7)?;
            Ok((emb, pts))
        });
        match result {
            Ok((emb, pts)) => {
                if let Some((id, blocks)) = self.last_blocks.take() {
                    let path = tsne::project(&blocks, &emb, &pts, tsne::PROJECT_K);
                    self.send(Reply::Path { id, path });
                }
                self.send(Reply::Map(Arc::new(SeedMap { model_dir, points: pts.clone() })));
                self.map = Some((emb, pts));
            }
            Err(e) => {
                // Do not try again for this model.
                self.map = Some((Vec::new(), Vec::new()));
                self.send(Reply::MapFailed(format!("{e:#}")));
            }
        }
    }
}

/// GloGen's encoder embedding of every seed, each under its own class.
fn seed_embeddings(model: &mut GlocalModel) -> Result<Vec<Vec<f32>>> {
    let seeds: Vec<(usize, Vec<f32>)> = model.seeds.iter().map(|s| (s.class, s.features.clone())).collect();
    let mut out = Vec::with_capacity(seeds.len());
    for (class, mut features) in seeds {
        model.spec.sparse_norm.normalize(&mut features);
        let class_vec = model.class_vector(class);
        out.push(model.embed(&features, &class_vec));
    }
    Ok(out)
}
