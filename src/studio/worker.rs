//! The background worker: owns the model, loads it, generates takes, builds the seed map
//! and writes exports, so the UI thread never waits. The UI sends [`Job`]s; the worker
//! answers with [`Reply`]s and wakes the UI with `request_repaint`.
//!
//! Cancelling: every generation has an id and the handle keeps the id of the one the UI
//! still wants. The progress callback stops a generation as soon as it is no longer
//! wanted (a newer edit, or the Cancel button), and queued requests that are no longer
//! wanted are skipped.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{channel, Receiver, Sender, TryRecvError};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context as _, Result};

use super::retarget::{self, PreviewFor, RetargetFailure, Retargeting};
use super::tsne;
use crate::data::joint_map::UserJointMap;
use crate::model::glocal::GlocalModel;
use crate::model::spec::ModelSpec;
use crate::motion::{Motion, Skeleton};
use crate::motion::contacts::FootContacts;
use crate::motion::cycle::Cycle;
use crate::synth::export::{export_with_contacts, prepare, ExportOptions};
use crate::synth::init::initial_features;
use crate::synth::render::class_color;
use crate::synth::own_start::take_on_rig;
use crate::synth::{GenerateOptions, Generated, InitPose, Request as TakeRequest, SegmentSpan, TakeCache, TakeEvents};

/// What the UI knows of a loaded model.
pub struct ModelInfo {
    pub dir: PathBuf,
    pub spec: ModelSpec,
    pub seeds: Vec<SeedInfo>,
    /// For each class, its seeds (as variants: positions among the class's seeds) from the
    /// most typical of the class to the least (see [`typical_order`]).
    pub typical: Vec<Vec<usize>>,
    pub has_locgen: bool,
    pub has_texture: bool,
}

impl ModelInfo {
    /// The variant the studio offers as a class's `rank`-th start (0: the most typical).
    pub fn typical_variant(&self, class: usize, rank: usize) -> usize {
        self.typical.get(class).and_then(|v| v.get(rank)).copied().unwrap_or(0)
    }

    /// The rank of a class's `variant` in [`ModelInfo::typical`] (inverse of `typical_variant`).
    pub fn typical_rank(&self, class: usize, variant: usize) -> usize {
        self.typical.get(class).and_then(|v| v.iter().position(|&x| x == variant)).unwrap_or(0)
    }
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
#[derive(Clone)]
pub struct Take {
    pub id: u64,
    /// The model folder it was generated with.
    pub model_dir: PathBuf,
    pub motion: Arc<Motion>,
    pub segments: Vec<SegmentSpan>,
    /// Class colour of every frame.
    pub frame_colors: Arc<Vec<[u8; 3]>>,
    pub block_classes: Vec<usize>,
    /// Each block's place in the seed map (empty until the map exists).
    pub path: Vec<[f32; 2]>,
    pub options: GenerateOptions,
    /// What the take could not do as asked (see [`crate::synth::Generated::warnings`]).
    pub warnings: Vec<String>,
    /// Each foot's contacts as the foot lock planted them (or as found, with the lock off).
    pub contacts: Arc<FootContacts>,
    /// A looping take's cycle (see [`crate::synth::Generated::cycle`]).
    pub cycle: Option<Cycle>,
    pub millis: f64,
    /// False while the take is still being made: these are its first frames, final.
    pub complete: bool,
}

impl Take {
    /// The take `generated` made for request `id` (`complete` false while it is still being
    /// made: its frames so far).
    fn of(id: u64, model_dir: PathBuf, generated: Generated, options: GenerateOptions, path: Vec<[f32; 2]>, millis: f64, complete: bool) -> Self {
        let frames = generated.motion.frames();
        let mut colors = vec![[128, 128, 128]; frames];
        for s in &generated.segments {
            for c in &mut colors[s.start_frame.min(frames)..s.end_frame.min(frames)] {
                *c = class_color(s.class);
            }
        }
        Take {
            id,
            model_dir,
            motion: Arc::new(generated.motion),
            segments: generated.segments,
            frame_colors: Arc::new(colors),
            block_classes: generated.block_classes,
            path,
            options,
            warnings: generated.warnings,
            contacts: Arc::new(generated.contacts),
            cycle: generated.cycle,
            millis,
            complete,
        }
    }
}

/// What the worker does as a take is made: tells the UI how far it is (and stops when the
/// take is no longer wanted), and sends the take's frames so far.
struct Streaming<'a> {
    id: u64,
    model_dir: &'a PathBuf,
    options: &'a GenerateOptions,
    wanted: &'a AtomicU64,
    replies: &'a Sender<Reply>,
    ctx: &'a egui::Context,
    last_sent: f32,
    start: Instant,
}

impl TakeEvents for Streaming<'_> {
    fn progress(&mut self, fraction: f32) -> bool {
        if fraction - self.last_sent >= 0.05 || fraction >= 1.0 {
            self.last_sent = fraction;
            let _ = self.replies.send(Reply::Progress { id: self.id, fraction });
            self.ctx.request_repaint();
        }
        self.wanted.load(Ordering::SeqCst) == self.id
    }

    fn wants_frames(&self) -> bool {
        self.wanted.load(Ordering::SeqCst) == self.id
    }

    fn frames(&mut self, so_far: Generated) {
        let millis = self.start.elapsed().as_secs_f64() * 1e3;
        let take = Take::of(self.id, self.model_dir.clone(), so_far, self.options.clone(), Vec::new(), millis, false);
        let _ = self.replies.send(Reply::Streamed(Arc::new(take)));
        self.ctx.request_repaint();
    }
}

#[derive(Clone)]
pub enum Job {
    LoadModel(PathBuf),
    Generate { id: u64, request: TakeRequest },
    /// Retargets a frame of a BVH file onto the model for a preview (see [`retarget`]).
    Retarget { purpose: PreviewFor, path: PathBuf, frame: usize, joint_map: Option<UserJointMap> },
    /// Checks that an initial pose can start a take on the current model.
    CheckInit(InitPose),
    Export(ExportJob),
}

/// A take to write: frames `range` of `motion` (the whole take, which a rig's own start is
/// read against), its `segments` and `contacts` over that range (a JSON export keeps them),
/// on the rig `options` may name with `request`'s joint map.
#[derive(Clone)]
pub struct ExportJob {
    pub motion: Arc<Motion>,
    pub range: std::ops::Range<usize>,
    pub segments: Vec<SegmentSpan>,
    pub contacts: FootContacts,
    pub path: PathBuf,
    pub options: ExportOptions,
    pub source: Arc<Skeleton>,
    pub request: TakeRequest,
}

impl Job {
    /// The reply that reports this request's failure (a panic while serving it).
    fn failure(&self, error: String) -> Reply {
        match self {
            Job::LoadModel(dir) => Reply::ModelFailed { dir: dir.clone(), error },
            Job::Generate { id, .. } => Reply::GenerateFailed { id: *id, error, cancelled: false },
            Job::CheckInit(init) => Reply::InitFailed { init: init.clone(), error },
            Job::Retarget { purpose, path, frame, .. } => Reply::Retarget(Retargeting::Failed(Arc::new(RetargetFailure { purpose: *purpose, path: path.clone(), frame: *frame, error, joints: Default::default() }))),
            Job::Export(job) => Reply::ExportFailed { path: job.path.clone(), error },
        }
    }
}

pub enum Reply {
    ModelLoaded(Arc<ModelInfo>),
    ModelFailed { dir: PathBuf, error: String },
    Map(Arc<SeedMap>),
    MapFailed(String),
    Progress { id: u64, fraction: f32 },
    /// The first frames of a take still being made.
    Streamed(Arc<Take>),
    Generated(Arc<Take>),
    GenerateFailed { id: u64, error: String, cancelled: bool },
    /// The map path of a take generated before the map existed.
    Path { id: u64, path: Vec<[f32; 2]> },
    InitOk(InitPose),
    InitFailed { init: InitPose, error: String },
    Retarget(Retargeting),
    Exported(PathBuf),
    ExportFailed { path: PathBuf, error: String },
}

/// The UI's end of the worker.
pub struct Worker {
    tx: Sender<Job>,
    rx: Receiver<Reply>,
    wanted: Arc<AtomicU64>,
    next_id: u64,
    ctx: egui::Context,
    /// Requests that could not be sent because the worker thread was gone (it is started
    /// again at once); the app reports them.
    lost: usize,
}

/// The worker thread, listening on `requests`.
fn start_thread(ctx: egui::Context, wanted: Arc<AtomicU64>) -> std::io::Result<(Sender<Job>, Receiver<Reply>)> {
    let (tx, requests) = channel();
    let (replies, rx) = channel();
    let state = WorkerState { ctx, replies, wanted, model: None, map: None, last_blocks: None, cache: TakeCache::default(), last_embeddings: Vec::new() };
    std::thread::Builder::new().name("glocal-worker".into()).spawn(move || state.run(&requests))?;
    Ok((tx, rx))
}

impl Worker {
    pub fn spawn(ctx: egui::Context) -> Self {
        let wanted = Arc::new(AtomicU64::new(0));
        let (tx, rx) = start_thread(ctx.clone(), wanted.clone()).expect("cannot start the worker thread");
        Self { tx, rx, wanted, next_id: 1, ctx, lost: 0 }
    }

    /// Sends a request; if the worker thread is gone, starts a new one (without a model:
    /// the app loads it again) and counts the request as lost.
    fn send(&mut self, request: Job) {
        if self.tx.send(request).is_err() {
            self.lost += 1;
            if let Ok((tx, rx)) = start_thread(self.ctx.clone(), self.wanted.clone()) {
                (self.tx, self.rx) = (tx, rx);
            }
        }
    }

    /// How many requests were lost since the last call (see [`Worker::send`]).
    pub fn take_lost(&mut self) -> usize {
        std::mem::take(&mut self.lost)
    }

    pub fn load_model(&mut self, dir: PathBuf) {
        self.send(Job::LoadModel(dir));
    }

    /// Starts a generation (cancelling any older one); returns its id.
    pub fn generate(&mut self, request: TakeRequest) -> u64 {
        let id = self.fresh_id();
        self.wanted.store(id, Ordering::SeqCst);
        self.send(Job::Generate { id, request });
        id
    }

    /// Stops the generation under way, if any.
    pub fn cancel(&mut self) {
        let id = self.fresh_id();
        self.wanted.store(id, Ordering::SeqCst);
    }

    pub fn check_init(&mut self, init: InitPose) {
        self.send(Job::CheckInit(init));
    }

    pub fn retarget(&mut self, purpose: PreviewFor, path: PathBuf, frame: usize, joint_map: Option<UserJointMap>) {
        self.send(Job::Retarget { purpose, path, frame, joint_map });
    }

    pub fn export(&mut self, job: ExportJob) {
        self.send(Job::Export(job));
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
    /// The last take, resumed by the next generation where it begins to differ.
    cache: TakeCache,
    /// The block embeddings of the last take: a held block's place on the seed map.
    last_embeddings: Vec<Vec<f32>>,
}

impl WorkerState {
    /// Sends a reply; false when the UI is gone (the worker then stops).
    fn send(&self, reply: Reply) -> bool {
        let sent = self.replies.send(reply).is_ok();
        self.ctx.request_repaint();
        sent
    }

    /// Serves requests until the UI goes away. A panic while serving one is caught and
    /// reported as that request's failure; the worker keeps serving.
    fn run(mut self, requests: &Receiver<Job>) {
        loop {
            let request = match requests.try_recv() {
                Ok(r) => r,
                Err(TryRecvError::Disconnected) => return,
                Err(TryRecvError::Empty) => {
                    // Idle: build the seed map if the model has none yet, then wait.
                    if self.model.is_some() && self.map.is_none() {
                        if catch_unwind(AssertUnwindSafe(|| self.build_map())).is_err() {
                            self.map = Some((Vec::new(), Vec::new()));
                            self.send(Reply::MapFailed("internal error while building the seed map".into()));
                        }
                        continue;
                    }
                    match requests.recv() {
                        Ok(r) => r,
                        Err(_) => return,
                    }
                }
            };
            let reply = match catch_unwind(AssertUnwindSafe(|| self.serve(request.clone()))) {
                Ok(Some(reply)) => reply,
                Ok(None) => continue,
                Err(panic) => request.failure(format!("internal error ({}); the studio carries on, please report it", panic_text(panic.as_ref()))),
            };
            if !self.send(reply) {
                return;
            }
        }
    }

    /// Serves one request; returns the reply still to send (generation and model loads
    /// send theirs on the way).
    fn serve(&mut self, request: Job) -> Option<Reply> {
        match request {
            Job::LoadModel(dir) => self.load(dir),
            Job::Generate { id, request } => {
                if self.wanted.load(Ordering::SeqCst) == id {
                    self.generate(id, &request);
                }
            }
            Job::Retarget { purpose, path, frame, joint_map } => {
                let Some(model) = self.model.as_ref() else {
                    return Some(Job::Retarget { purpose, path: path.clone(), frame, joint_map }.failure("no model is loaded".into()));
                };
                return Some(Reply::Retarget(retarget::preview(&model.spec, purpose, path, frame, joint_map.as_ref())));
            }
            Job::CheckInit(init) => {
                return Some(match self.model.as_ref().context("no model is loaded").and_then(|m| initial_features(m, &init)) {
                    Ok(_) => Reply::InitOk(init),
                    Err(e) => Reply::InitFailed { init, error: format!("{e:#}") },
                });
            }
            Job::Export(job) => {
                let path = job.path.clone();
                return Some(match self.export(job) {
                    Ok(()) => Reply::Exported(path),
                    Err(e) => Reply::ExportFailed { path, error: format!("{e:#}") },
                });
            }
        }
        None
    }

    /// Writes `job`'s frames, on its rig if it names one.
    fn export(&self, job: ExportJob) -> Result<()> {
        let ExportJob { motion, range, segments, contacts, path, options, source, request } = job;
        let on_rig = match &options.rig {
            Some(rig) => Arc::new(take_on_rig(self.model.as_ref().context("no model is loaded")?, &request, &motion, rig)?),
            None => motion,
        };
        let frames = if range == (0..on_rig.frames()) { on_rig } else { Arc::new(on_rig.slice(range.start, range.end)) };
        let (m, s) = prepare(&frames, &segments, &options, &source)?;
        export_with_contacts(&m, &s, Some(&contacts), &path)
    }

    fn load(&mut self, dir: PathBuf) {
        match GlocalModel::load(&dir) {
            Ok(model) => {
                let info = ModelInfo {
                    dir: dir.clone(),
                    spec: model.spec.clone(),
                    seeds: model.seeds.iter().map(|s| SeedInfo { class: s.class, clip: s.clip.clone(), frame: s.frame }).collect(),
                    typical: typical_order(&model),
                    has_locgen: model.has_locgen(),
                    has_texture: model.texture().is_some(),
                };
                self.model = Some(model);
                self.cache.clear();
                self.last_embeddings.clear();
                self.map = None;
                self.last_blocks = None;
                self.send(Reply::ModelLoaded(Arc::new(info)));
            }
            // The model in use, if any, stays.
            Err(e) => {
                self.send(Reply::ModelFailed { dir, error: format!("{e:#}") });
            }
        }
    }

    /// Generates the take `request` asks for, resuming the last one where it begins to
    /// differ, and streams its frames to the UI as they become final.
    fn generate(&mut self, id: u64, request: &TakeRequest) {
        let Some(model) = self.model.as_ref() else {
            self.send(Reply::GenerateFailed { id, error: "no model is loaded".into(), cancelled: false });
            return;
        };
        let mut events = Streaming { id, model_dir: &model.dir, options: &request.options, wanted: &self.wanted, replies: &self.replies, ctx: &self.ctx, last_sent: 0.0, start: Instant::now() };
        let result = request.generate_with(model, &mut self.cache, &mut events);
        let millis = events.start.elapsed().as_secs_f64() * 1e3;
        match result {
            Ok(mut g) => {
                g.block_embeddings = with_held_blocks(g.block_embeddings, &self.last_embeddings);
                self.last_embeddings = g.block_embeddings.clone();
                let path = self.map.as_ref().filter(|(emb, _)| !emb.is_empty()).map(|(emb, pts)| tsne::project(&g.block_embeddings, emb, pts, tsne::PROJECT_K)).unwrap_or_default();
                let model_dir = model.dir.clone();
                if self.map.is_none() {
                    self.last_blocks = Some((id, g.block_embeddings.clone()));
                }
                let take = Take::of(id, model_dir, g, request.options.clone(), path, millis, true);
                self.send(Reply::Generated(Arc::new(take)));
            }
            Err(e) => {
                let cancelled = e.downcast_ref() == Some(&crate::synth::Error::Cancelled) || self.wanted.load(Ordering::SeqCst) != id;
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

/// The text of a caught panic.
/// A take's block embeddings with its held blocks' (which GloGen did not make, so have none)
/// filled in: the last take's block at the same place where it has one, else the nearest
/// block of this take before it, or after it.
fn with_held_blocks(mut blocks: Vec<Vec<f32>>, last: &[Vec<f32>]) -> Vec<Vec<f32>> {
    for b in 0..blocks.len() {
        if blocks[b].is_empty() {
            if let Some(e) = last.get(b).filter(|e| !e.is_empty()) {
                blocks[b] = e.clone();
            }
        }
    }
    let known: Vec<usize> = (0..blocks.len()).filter(|&b| !blocks[b].is_empty()).collect();
    for b in 0..blocks.len() {
        if blocks[b].is_empty() {
            let nearest = known.iter().rev().find(|&&k| k < b).or_else(|| known.iter().find(|&&k| k > b));
            if let Some(&k) = nearest {
                blocks[b] = blocks[k].clone();
            }
        }
    }
    blocks
}

fn panic_text(panic: &(dyn std::any::Any + Send)) -> String {
    panic.downcast_ref::<&str>().map(|s| s.to_string()).or_else(|| panic.downcast_ref::<String>().cloned()).unwrap_or_else(|| "a panic".into())
}

/// For each class, its seed windows ordered from the most typical to the least: by mean
/// distance (normalised features) to the class's other windows. A class's first window is
/// often the start of a clip (a "sitting" clip starts standing), so the medoid, not the first,
/// is what a start "by class" should look like.
pub fn typical_order(model: &GlocalModel) -> Vec<Vec<usize>> {
    let normalized: Vec<(usize, Vec<f32>)> = model
        .seeds
        .iter()
        .map(|s| {
            let mut f = s.features.clone();
            model.spec.sparse_norm.normalize(&mut f);
            (s.class, f)
        })
        .collect();
    (0..model.spec.classes.len())
        .map(|class| {
            let mine: Vec<&Vec<f32>> = normalized.iter().filter(|(c, _)| *c == class).map(|(_, f)| f).collect();
            let spread = |a: &Vec<f32>| mine.iter().map(|b| a.iter().zip(b.iter()).map(|(x, y)| (x - y) * (x - y)).sum::<f32>().sqrt()).sum::<f32>();
            let mut order: Vec<(usize, f32)> = mine.iter().enumerate().map(|(k, f)| (k, spread(f))).collect();
            order.sort_by(|a, b| a.1.total_cmp(&b.1));
            order.into_iter().map(|(k, _)| k).collect()
        })
        .collect()
}

/// GloGen's encoder embedding of every seed, each under its own class.
fn seed_embeddings(model: &GlocalModel) -> Result<Vec<Vec<f32>>> {
    let seeds: Vec<(usize, Vec<f32>)> = model.seeds.iter().map(|s| (s.class, s.features.clone())).collect();
    let mut out = Vec::with_capacity(seeds.len());
    for (class, mut features) in seeds {
        model.spec.sparse_norm.normalize(&mut features);
        let class_vec = model.class_vector(class);
        out.push(model.embed(&features, &class_vec));
    }
    Ok(out)
}
