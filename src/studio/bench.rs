//! Frame time of the studio during playback, against an empty eframe window of the same
//! size: each runs in its own process (a process can open only one event loop), under the
//! same display, and the ratio is what counts on a shared machine.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use anyhow::Result;
use serde::{Deserialize, Serialize};

use super::app::{StudioApp, StudioOptions};
use super::viewport::Viewport;

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct FrameStats {
    pub frames: usize,
    pub mean_ms: f64,
    pub median_ms: f64,
    pub p95_ms: f64,
    pub width: f32,
    pub height: f32,
}

impl FrameStats {
    fn from_intervals(mut ms: Vec<f64>, size: egui::Vec2) -> Self {
        if ms.is_empty() {
            return Self::default();
        }
        let mean = ms.iter().sum::<f64>() / ms.len() as f64;
        ms.sort_by(f64::total_cmp);
        Self {
            frames: ms.len(),
            mean_ms: mean,
            median_ms: ms[ms.len() / 2],
            p95_ms: ms[(ms.len() * 95 / 100).min(ms.len() - 1)],
            width: size.x,
            height: size.y,
        }
    }
}

/// Wall time between consecutive frames, once `ready` says the measured state is reached.
struct Timed<A> {
    inner: A,
    seconds: f64,
    last: Option<Instant>,
    started: Option<Instant>,
    intervals: Vec<f64>,
    out: Arc<Mutex<FrameStats>>,
    ready: fn(&mut A) -> bool,
}

impl<A: eframe::App> eframe::App for Timed<A> {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        self.inner.ui(ui, frame);
        let ctx = ui.ctx().clone();
        ctx.request_repaint();
        if !(self.ready)(&mut self.inner) {
            return;
        }
        let now = Instant::now();
        let started = *self.started.get_or_insert(now);
        if let Some(last) = self.last.replace(now) {
            self.intervals.push((now - last).as_secs_f64() * 1e3);
        }
        if (now - started).as_secs_f64() >= self.seconds {
            let size = ctx.content_rect().size();
            if let Ok(mut out) = self.out.lock() {
                *out = FrameStats::from_intervals(std::mem::take(&mut self.intervals), size);
            }
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
    }
}

struct Empty;

impl eframe::App for Empty {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        egui::CentralPanel::default().show(ui, |_| {});
    }
}

/// Runs one window for `seconds` of measured frames: the studio playing its default take
/// with ghosts on, or (`empty`) a window with nothing in it.
pub fn measure(empty: bool, seconds: f64) -> Result<FrameStats> {
    let out = Arc::new(Mutex::new(FrameStats::default()));
    let options = eframe::NativeOptions {
        renderer: eframe::Renderer::Wgpu,
        viewport: egui::ViewportBuilder::default().with_inner_size([1280.0, 800.0]).with_title("Glocal Studio benchmark"),
        ..Default::default()
    };
    let sink = out.clone();
    eframe::run_native(
        "glocal-bench",
        options,
        Box::new(move |cc| -> std::result::Result<Box<dyn eframe::App>, _> {
            if empty {
                return Ok(Box::new(Timed { inner: Empty, seconds, last: None, started: None, intervals: Vec::new(), out: sink, ready: |_| true }));
            }
            if let Some(rs) = &cc.wgpu_render_state {
                Viewport::register(rs);
            }
            let options = StudioOptions { autosave: None, restore_autosave: false, ..Default::default() };
            let app = StudioApp::new(cc, options);
            Ok(Box::new(Timed {
                inner: app,
                seconds,
                last: None,
                started: None,
                intervals: Vec::new(),
                out: sink,
                ready: |app: &mut StudioApp| {
                    let frames = app.take.as_ref().map_or(0, |t| t.motion.frames());
                    if frames > 1 && !app.playback.playing {
                        app.doc.view.ghosts = app.doc.view.ghosts.max(3);
                        app.playback.toggle(frames, &app.doc.playback);
                    }
                    app.playback.playing
                },
            }))
        }),
    )
    .map_err(|e| anyhow::anyhow!("the benchmark window could not open: {e}"))?;
    let stats = out.lock().map_err(|_| anyhow::anyhow!("poisoned"))?.clone();
    if stats.frames == 0 {
        anyhow::bail!("no frames were measured: the window closed before a take played");
    }
    Ok(stats)
}
