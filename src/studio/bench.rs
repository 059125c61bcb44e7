//! Frame time of the studio during playback, against an empty eframe window of the same
//! size: each runs in its own process (a process can open only one event loop), under the
//! same display, and the ratio is what counts on a shared machine.
//!
//! What is timed is the wall time between consecutive [`eframe::App::ui`] calls, i.e. whole
//! eframe frames: the app's ui, egui's tessellation, the wgpu paint (the viewport's offscreen
//! scene included) and the present. Both windows present without vsync
//! (`PresentMode::AutoNoVsync`), so the interval is the cost of a frame, not the display's
//! refresh (with vsync, two windows both faster than the refresh would read the same and
//! give a ratio of 1). Besides wall time each window reports its process CPU time
//! per frame (every thread, llvmpipe's rasteriser threads included), which a loaded machine
//! disturbs much less.
//!
//! The studio is measured in its steady state: the model loaded, the default take (or, with
//! `--take-seconds`, a long timeline of the model's classes) generated, the worker idle (the
//! seed map built), playing with ghosts and the trail on; the first frames after that are not
//! counted (pipeline and texture creation, the take's upload).
//!
//! [`measure_memory`] reads the studio's resident memory (VmRSS and its peak VmHWM from
//! /proc/self/status) with its default take, holding a long take, and after closing it; and
//! at each step again once glibc's allocator has given its free memory back, which tells
//! what the studio holds from what the allocator keeps.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Result;
use serde::{Deserialize, Serialize};

use super::app::{StudioApp, StudioOptions};
use super::viewport::Viewport;
use crate::synth::{Segment, Timeline};

/// Frames not counted once the measured state is reached.
const WARMUP_FRAMES: usize = 10;
/// Longest wait for the studio to reach its measured state (model, take, seed map).
const READY_TIMEOUT: Duration = Duration::from_secs(240);

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct FrameStats {
    pub frames: usize,
    pub mean_ms: f64,
    pub median_ms: f64,
    pub p95_ms: f64,
    /// Process CPU time (all threads) per frame, milliseconds.
    #[serde(default)]
    pub cpu_ms: f64,
    pub width: f32,
    pub height: f32,
    /// Every frame interval, milliseconds (children hand them to the parent, which pools
    /// several runs; not printed by the parent).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub intervals_ms: Vec<f64>,
    /// Process CPU time over the measured frames, milliseconds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cpu_total_ms: Option<f64>,
}

impl FrameStats {
    pub fn from_intervals(ms: Vec<f64>, cpu_total_ms: f64, size: egui::Vec2) -> Self {
        if ms.is_empty() {
            return Self::default();
        }
        let mut sorted = ms.clone();
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len();
        Self {
            frames: n,
            mean_ms: sorted.iter().sum::<f64>() / n as f64,
            median_ms: if n % 2 == 1 { sorted[n / 2] } else { (sorted[n / 2 - 1] + sorted[n / 2]) / 2.0 },
            p95_ms: sorted[((n as f64 * 0.95).ceil() as usize).clamp(1, n) - 1],
            cpu_ms: cpu_total_ms / n as f64,
            width: size.x,
            height: size.y,
            intervals_ms: ms,
            cpu_total_ms: Some(cpu_total_ms),
        }
    }

    /// Pools the frames of several runs of the same window.
    pub fn pool(runs: &[FrameStats]) -> Self {
        let ms: Vec<f64> = runs.iter().flat_map(|r| r.intervals_ms.iter().copied()).collect();
        let cpu = runs.iter().filter_map(|r| r.cpu_total_ms).sum();
        let size = runs.first().map_or(egui::Vec2::ZERO, |r| egui::vec2(r.width, r.height));
        let mut pooled = Self::from_intervals(ms, cpu, size);
        pooled.intervals_ms.clear();
        pooled.cpu_total_ms = None;
        pooled
    }
}

/// CPU time of this process so far (user + system, every thread), milliseconds.
fn process_cpu_ms() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else { return 0.0 };
    // The command name (field 2) may hold spaces; the fields after its ')' are plain.
    let Some(rest) = stat.rfind(')').map(|i| &stat[i + 1..]) else { return 0.0 };
    let fields: Vec<&str> = rest.split_whitespace().collect();
    // utime and stime are fields 14 and 15 of the whole line, 12 and 13 after the name.
    let ticks = |k: usize| fields.get(k).and_then(|s| s.parse::<f64>().ok()).unwrap_or(0.0);
    // Linux reports them in USER_HZ, which is 100 on every supported architecture.
    (ticks(11) + ticks(12)) * 10.0
}

/// Wall time between consecutive frames, once `ready` says the measured state is reached.
struct Timed<A> {
    inner: A,
    seconds: f64,
    /// Frames seen in the measured state (the first `WARMUP_FRAMES` are not timed).
    seen: usize,
    last: Option<Instant>,
    started: Option<(Instant, f64)>,
    opened: Instant,
    intervals: Vec<f64>,
    ready: fn(&mut A) -> bool,
}

impl<A> Timed<A> {
    fn new(inner: A, seconds: f64, ready: fn(&mut A) -> bool) -> Self {
        Self { inner, seconds, seen: 0, last: None, started: None, opened: Instant::now(), intervals: Vec::new(), ready }
    }
}

/// What a bench does in the window it measures, after each of the app's frames.
trait Bench {
    type App: eframe::App;
    type Output;
    fn app(&self) -> &Self::App;
    fn app_mut(&mut self) -> &mut Self::App;
    /// Looks at the frame just drawn; the bench's result once it is over.
    fn frame(&mut self, ctx: &egui::Context) -> Option<Result<Self::Output, String>>;
}

/// A bench's window: the app's frames, repainted without pause until the bench has its
/// result, which goes to `out`; then the window closes.
struct BenchWindow<B: Bench> {
    bench: B,
    out: Arc<Mutex<Result<B::Output, String>>>,
    /// The result is written: eframe still runs a frame or two after `Close`, which must not
    /// overwrite it.
    done: bool,
}

impl<B: Bench> BenchWindow<B> {
    fn new(bench: B, out: Arc<Mutex<Result<B::Output, String>>>) -> Self {
        Self { bench, out, done: false }
    }
}

impl<B: Bench> eframe::App for BenchWindow<B> {
    /// The studio's panels show the window's clear colour: forwarded so the measured window
    /// looks (and costs) exactly like the real one.
    fn clear_color(&self, visuals: &egui::Visuals) -> [f32; 4] {
        self.bench.app().clear_color(visuals)
    }

    fn logic(&mut self, ctx: &egui::Context, frame: &mut eframe::Frame) {
        self.bench.app_mut().logic(ctx, frame);
    }

    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        self.bench.app_mut().ui(ui, frame);
        let ctx = ui.ctx().clone();
        if self.done {
            return;
        }
        ctx.request_repaint();
        if let Some(result) = self.bench.frame(&ctx) {
            if let Ok(mut out) = self.out.lock() {
                *out = result;
            }
            self.done = true;
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
    }
}

impl<A: eframe::App> Bench for Timed<A> {
    type App = A;
    type Output = FrameStats;

    fn app(&self) -> &A {
        &self.inner
    }

    fn app_mut(&mut self) -> &mut A {
        &mut self.inner
    }

    fn frame(&mut self, ctx: &egui::Context) -> Option<Result<FrameStats, String>> {
        if !(self.ready)(&mut self.inner) {
            let late = self.opened.elapsed() > READY_TIMEOUT;
            return late.then(|| Err(format!("the studio did not reach playback within {} s", READY_TIMEOUT.as_secs())));
        }
        self.seen += 1;
        if self.seen <= WARMUP_FRAMES {
            return None;
        }
        let now = Instant::now();
        let (started, cpu_start) = *self.started.get_or_insert_with(|| (now, process_cpu_ms()));
        if let Some(last) = self.last.replace(now) {
            self.intervals.push((now - last).as_secs_f64() * 1e3);
        }
        if (now - started).as_secs_f64() >= self.seconds && !self.intervals.is_empty() {
            let cpu = process_cpu_ms() - cpu_start;
            let stats = FrameStats::from_intervals(std::mem::take(&mut self.intervals), cpu, ctx.content_rect().size());
            return Some(Ok(stats));
        }
        None
    }
}

struct Empty;

impl eframe::App for Empty {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        egui::CentralPanel::default().show(ui, |_| {});
    }
}

/// Which window a run measures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Window {
    /// An empty eframe window.
    Empty,
    /// The studio playing a take with ghosts and the trail on: its default take, or (with
    /// `take_seconds`) a timeline of the model's classes, [`LONG_SEGMENT_SECONDS`] each, that
    /// long.
    Studio { take_seconds: Option<f32> },
}

/// Length of each segment of a long bench take.
pub const LONG_SEGMENT_SECONDS: f32 = 60.0;

/// A timeline `seconds` long of the model's classes in turn, [`LONG_SEGMENT_SECONDS`] each
/// (the last one shorter if need be).
pub fn long_timeline(classes: &[String], seconds: f32) -> Timeline {
    let mut segments = Vec::new();
    let mut left = seconds;
    while left > 0.05 && !classes.is_empty() {
        let length = left.min(LONG_SEGMENT_SECONDS);
        segments.push(Segment::new(classes[segments.len() % classes.len()].clone(), length));
        left -= length;
    }
    Timeline { segments }
}

/// The studio with the take a bench asks for: once the model is loaded its timeline is
/// replaced by [`long_timeline`] (when `take_seconds` is given), and the take is the one
/// measured once it is generated.
struct BenchStudio {
    app: StudioApp,
    take_seconds: Option<f32>,
}

impl BenchStudio {
    /// Whether the studio shows the take asked for, idle (nothing generating, the seed map
    /// built: the worker builds it right after the first take, on another thread).
    fn has_take(&mut self) -> bool {
        let app = &mut self.app;
        let idle = app.engine.pending.is_none() && app.engine.model_loading.is_none() && app.engine.regen_at.is_none() && (app.engine.map.is_some() || app.engine.map_error.is_some());
        let Some(seconds) = self.take_seconds else {
            return idle && app.engine.take.as_ref().is_some_and(|t| t.motion.frames() >= 2);
        };
        let Some(model) = app.engine.model.clone() else { return false };
        let wanted = long_timeline(&model.spec.classes, seconds);
        if app.editing.doc.options.timeline != wanted {
            app.edit(|d| d.options.timeline = wanted.clone());
        }
        idle && app.engine.take.as_ref().is_some_and(|t| t.options.timeline == wanted && t.motion.frames() >= 2)
    }

    /// The measured state: the take asked for playing with ghosts and the trail on.
    fn ready(&mut self) -> bool {
        if !self.has_take() {
            return false;
        }
        start_playing(&mut self.app);
        self.app.playback.playing
    }
}

/// Plays the take shown with (at least) three ghosts and the trail.
fn start_playing(app: &mut StudioApp) {
    let frames = app.engine.take.as_ref().map_or(0, |t| t.motion.frames());
    if !app.playback.playing {
        let view = &mut app.editing.doc.view;
        view.ghosts = view.ghosts.max(3);
        view.trail = true;
        app.playback.toggle(frames, &app.editing.doc.playback);
    }
}

impl eframe::App for BenchStudio {
    fn clear_color(&self, visuals: &egui::Visuals) -> [f32; 4] {
        self.app.clear_color(visuals)
    }

    fn logic(&mut self, ctx: &egui::Context, frame: &mut eframe::Frame) {
        self.app.logic(ctx, frame);
    }

    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        self.app.ui(ui, frame);
    }
}

fn window_options() -> eframe::NativeOptions {
    let mut options = eframe::NativeOptions {
        renderer: eframe::Renderer::Wgpu,
        viewport: egui::ViewportBuilder::default().with_inner_size([1280.0, 800.0]).with_title("Glocal Studio benchmark"),
        persist_window: false,
        ..Default::default()
    };
    options.wgpu_options.surface.present_mode = eframe::wgpu::PresentMode::AutoNoVsync;
    options
}

/// The studio as the benches run it: nothing remembered between runs, the viewport's
/// pipelines installed.
fn bench_studio(cc: &eframe::CreationContext<'_>, take_seconds: Option<f32>) -> BenchStudio {
    if let Some(rs) = &cc.wgpu_render_state {
        Viewport::register(rs);
    }
    let options = StudioOptions { autosave: None, restore_autosave: false, ..Default::default() };
    BenchStudio { app: StudioApp::new(cc, options), take_seconds }
}

/// Runs one window for `seconds` of measured frames.
pub fn measure(window: Window, seconds: f64) -> Result<FrameStats> {
    let stats = run_window(move |cc, sink| match window {
        Window::Empty => Box::new(BenchWindow::new(Timed::new(Empty, seconds, |_| true), sink)),
        Window::Studio { take_seconds } => Box::new(BenchWindow::new(Timed::new(bench_studio(cc, take_seconds), seconds, BenchStudio::ready), sink)),
    })?;
    if stats.frames < 2 {
        anyhow::bail!("only {} frames were measured", stats.frames);
    }
    Ok(stats)
}

/// Resident memory of this process at one point of the memory bench, megabytes.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct MemoryPoint {
    pub what: String,
    /// Frames of the take shown.
    pub frames: usize,
    /// VmRSS: resident now.
    pub rss_mb: f64,
    /// VmHWM: the most resident so far.
    pub peak_mb: f64,
    /// VmRSS once the allocator has given its free memory back (glibc's `malloc_trim`):
    /// what the studio still holds, without what the allocator keeps for later.
    pub trimmed_mb: f64,
}

/// Gives the allocator's free memory back to the system, where it can (glibc).
fn trim_heap() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only releases free memory; it has no preconditions.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// A field of /proc/self/status in kB (VmRSS, VmHWM), as megabytes.
fn status_mb(field: &str) -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let kb = status.lines().find_map(|l| l.strip_prefix(field)?.strip_prefix(':')?.trim().strip_suffix("kB")?.trim().parse::<f64>().ok());
    kb.unwrap_or(0.0) / 1024.0
}

/// The steps of the memory bench, in order.
#[derive(Clone, Copy, Debug, PartialEq)]
enum MemoryStep {
    /// The model loaded, its default take playing.
    Default,
    /// The long take playing.
    Long,
    /// File > New: the default timeline's take playing (the long one is now the previous take).
    New,
    /// One more take generated (the long one gone from the previous take as well).
    Again,
}

/// Frames played at each step before its memory is read (the viewport has uploaded the take).
const MEMORY_FRAMES: usize = 30;

/// The studio going through [`MemoryStep`]s, reading its memory at each.
struct MemoryRun {
    studio: BenchStudio,
    long_seconds: f32,
    step: MemoryStep,
    /// Frames played at this step.
    played: usize,
    /// The take's id when the step began (a step that generates waits for another).
    take_before: Option<u64>,
    opened: Instant,
    points: Vec<MemoryPoint>,
}

impl MemoryRun {
    fn take_id(&self) -> Option<u64> {
        self.studio.app.engine.take.as_ref().map(|t| t.id)
    }

    /// Whether the step's take is on screen and playing.
    fn step_ready(&mut self) -> bool {
        let new_take = self.take_id() != self.take_before;
        let ready = match self.step {
            MemoryStep::Default | MemoryStep::Long => self.studio.has_take(),
            MemoryStep::New | MemoryStep::Again => new_take && self.studio.has_take(),
        };
        if ready {
            start_playing(&mut self.studio.app);
        }
        ready
    }

    /// Reads the memory of the step just played and starts the next one; after the last, the
    /// points read.
    fn next_step(&mut self) -> Option<Vec<MemoryPoint>> {
        let frames = self.studio.app.engine.take.as_ref().map_or(0, |t| t.motion.frames());
        let what = match self.step {
            MemoryStep::Default => "model loaded, default take".to_string(),
            MemoryStep::Long => format!("{:.0}-minute take", self.long_seconds / 60.0),
            MemoryStep::New => "File > New (the long take is the previous take)".to_string(),
            MemoryStep::Again => "one more take (the long one no longer held)".to_string(),
        };
        let (rss_mb, peak_mb) = (status_mb("VmRSS"), status_mb("VmHWM"));
        trim_heap();
        self.points.push(MemoryPoint { what, frames, rss_mb, peak_mb, trimmed_mb: status_mb("VmRSS") });
        self.played = 0;
        self.take_before = self.take_id();
        let app = &mut self.studio.app;
        app.playback.playing = false;
        self.step = match self.step {
            MemoryStep::Default => {
                self.studio.take_seconds = Some(self.long_seconds);
                MemoryStep::Long
            }
            MemoryStep::Long => {
                self.studio.take_seconds = None;
                app.new_project();
                MemoryStep::New
            }
            MemoryStep::New => {
                app.regenerate();
                MemoryStep::Again
            }
            MemoryStep::Again => return Some(std::mem::take(&mut self.points)),
        };
        None
    }
}

impl Bench for MemoryRun {
    type App = BenchStudio;
    type Output = Vec<MemoryPoint>;

    fn app(&self) -> &BenchStudio {
        &self.studio
    }

    fn app_mut(&mut self) -> &mut BenchStudio {
        &mut self.studio
    }

    fn frame(&mut self, _ctx: &egui::Context) -> Option<Result<Vec<MemoryPoint>, String>> {
        if self.opened.elapsed() > MEMORY_TIMEOUT {
            return Some(Err(format!("the memory bench did not finish within {} s (at {:?})", MEMORY_TIMEOUT.as_secs(), self.step)));
        }
        if !self.step_ready() {
            return None;
        }
        self.played += 1;
        if self.played < MEMORY_FRAMES {
            return None;
        }
        self.next_step().map(Ok)
    }
}

/// Longest the memory bench may take (a one-hour take is generated on the way).
const MEMORY_TIMEOUT: Duration = Duration::from_secs(1200);

/// The studio's resident memory: with its default take, holding a `long_seconds` take, after
/// File > New, and after one more take.
pub fn measure_memory(long_seconds: f32) -> Result<Vec<MemoryPoint>> {
    run_window(move |cc, sink| {
        let studio = bench_studio(cc, None);
        let run = MemoryRun { studio, long_seconds, step: MemoryStep::Default, played: 0, take_before: None, opened: Instant::now(), points: Vec::new() };
        Box::new(BenchWindow::new(run, sink))
    })
}

/// Opens the bench window `make` builds (handing it the slot its result goes to), runs it
/// until it closes, and returns the result.
fn run_window<T: Clone + 'static>(make: impl FnOnce(&eframe::CreationContext<'_>, Arc<Mutex<Result<T, String>>>) -> Box<dyn eframe::App> + 'static) -> Result<T> {
    let out = Arc::new(Mutex::new(Err("the window closed before it was measured".to_string())));
    let sink = out.clone();
    eframe::run_native("glocal-bench", window_options(), Box::new(move |cc| -> std::result::Result<Box<dyn eframe::App>, _> { Ok(make(cc, sink)) }))
        .map_err(|e| anyhow::anyhow!("the benchmark window could not open: {e}"))?;
    let result = out.lock().map_err(|_| anyhow::anyhow!("poisoned"))?.clone();
    result.map_err(|e| anyhow::anyhow!(e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_of_intervals() {
        let s = FrameStats::from_intervals((1..=20).map(f64::from).collect(), 40.0, egui::vec2(2.0, 1.0));
        assert_eq!(s.frames, 20);
        assert!((s.mean_ms - 10.5).abs() < 1e-9);
        assert!((s.median_ms - 10.5).abs() < 1e-9);
        assert!((s.p95_ms - 19.0).abs() < 1e-9);
        assert!((s.cpu_ms - 2.0).abs() < 1e-9);
        let pooled = FrameStats::pool(&[s.clone(), s]);
        assert_eq!(pooled.frames, 40);
        assert!((pooled.cpu_ms - 2.0).abs() < 1e-9);
        assert!(pooled.intervals_ms.is_empty());
    }

    #[test]
    fn cpu_time_grows() {
        let a = process_cpu_ms();
        let t = Instant::now();
        let mut x = 0u64;
        while t.elapsed() < Duration::from_millis(60) {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
        }
        std::hint::black_box(x);
        assert!(process_cpu_ms() >= a);
    }
}
