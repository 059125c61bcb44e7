//! What training each stage means: the windows of real motion it learns from, its prediction
//! and loss, and how it is validated. GloGen learns sparse blocks rolled out on its own
//! outputs and is validated by the rollout generation uses; LocGen learns the residual on
//! an interpolated dense window.

use anyhow::{Context, Result};
use candle_core::{Device, Tensor};
use glam::Vec3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::TrainOptions;
use crate::data::features::{FeatureLayout, Normalizer, Placement, ROOT_FEATURES};
use crate::model::block::{BlockWorkspace, Seq2SeqBlock};
use crate::model::corpus::{interpolated_window, sample_window, Corpus, Track};
use crate::model::glogen::GloGen;
use crate::model::loss::joint_flow_loss;
use crate::model::rollout::{rollout, OneClass};
use crate::model::seam::join_seams_tensor;
use crate::model::spec::{LossKind, ModelSpec};
use crate::model::target::{target_condition, target_flag, target_len, Target, Way};

/// Held-out windows a validation scores.
const VALIDATION_WINDOWS: usize = 256;

/// A held-out window: inputs, targets and where it starts, all fixed for the whole run.
pub(super) struct ValWindow {
    pub input: Vec<f32>,
    pub class: usize,
    pub style: Option<usize>,
    pub target_positions: Vec<Vec3>,
    pub start: Placement,
    /// GloGen: the last input pose repeated (zero-velocity); LocGen: the interpolation; the
    /// in-betweener: linear interpolation over the gap.
    pub baseline_positions: Vec<Vec3>,
}

/// One stage's training.
pub(super) trait StageTraining {
    /// The loss of one batch of windows drawn with `rng`.
    fn loss(&self, block: &Seq2SeqBlock, rng: &mut StdRng) -> Result<Tensor>;

    /// The held-out windows of the run (the same at every validation).
    fn validation_windows(&self) -> Vec<ValWindow>;

    /// Mean joint position error (skeleton units) of the block's prediction and of the
    /// stage's baseline over `windows`.
    fn validate(&self, block: &Seq2SeqBlock, windows: &[ValWindow]) -> Result<(f32, f32)>;
}

/// What every stage trains from.
pub(super) struct TrainingData<'a> {
    pub opts: &'a TrainOptions,
    pub corpus: &'a Corpus,
    pub spec: &'a ModelSpec,
    pub norm: &'a Normalizer,
}

impl TrainingData<'_> {
    pub(super) fn layout(&self) -> &FeatureLayout {
        &self.spec.layout
    }

    /// A batch of windows of `span` frames (after a frame before each): inputs `[B, T, D]`,
    /// targets `[B, T * target_blocks, D]` as `window` makes them from a track and its first
    /// frame, and each window's class vector (zeroed with the class-dropout probability, then
    /// zeros for the rest of the block's conditioning) and where it was drawn from.
    fn batch<'t>(&'t self, block: &Seq2SeqBlock, span: usize, target_blocks: usize, rng: &mut StdRng, window: impl Fn(&Track, usize) -> (Vec<f32>, Vec<f32>)) -> Result<Batch<'t>> {
        let (dim, b, cond_dim) = (self.layout().dim(), self.opts.optimiser.batch, block.cfg.cond_dim);
        let (mut xs, mut ys, mut conds, mut drawn) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for _ in 0..b {
            let (track, start) = sample_window(&self.corpus.train, self.corpus.classes.len(), span + self.spec.stride, rng).context("no training clip is long enough")?;
            let (x, y) = window(track, start + self.spec.stride);
            xs.extend(x);
            ys.extend(y);
            let mut c = vec![0f32; cond_dim];
            if cond_dim > 0 && rng.random::<f32>() >= self.spec.glogen.class_dropout {
                self.spec.set_labels(&mut c, track.class, track.style);
            }
            conds.extend(c);
            drawn.push((track, start + self.spec.stride));
        }
        let steps_in = xs.len() / b / dim;
        let x = Tensor::from_vec(xs, (b, steps_in, dim), &Device::Cpu)?;
        let y = Tensor::from_vec(ys, (b, steps_in * target_blocks, dim), &Device::Cpu)?;
        Ok(Batch { x, y, conds, drawn })
    }

    /// Held-out windows of `span` frames (after a frame before each) from the test split (the
    /// training split when there is none), as `window` makes them from a track and its
    /// first frame; the same at every call.
    pub(super) fn held_out(&self, span: usize, mut window: impl FnMut(&Track, usize) -> ValWindow) -> Vec<ValWindow> {
        let mut rng = StdRng::seed_from_u64(1234);
        let tracks = if self.corpus.test.is_empty() { &self.corpus.train } else { &self.corpus.test };
        let mut out = Vec::new();
        for _ in 0..VALIDATION_WINDOWS {
            let Some((track, start)) = sample_window(tracks, self.corpus.classes.len(), span + self.spec.stride, &mut rng) else { break };
            out.push(window(track, start + self.spec.stride));
        }
        out
    }
}

/// A training batch: inputs, targets, the conditioning rows `[B * cond_dim]` and each
/// window's track and first frame.
struct Batch<'t> {
    x: Tensor,
    y: Tensor,
    conds: Vec<f32>,
    drawn: Vec<(&'t Track, usize)>,
}

impl Batch<'_> {
    /// The conditioning as a tensor `[B, cond_dim]`, none for a block without any.
    fn cond(&self, rows: &[f32]) -> Result<Option<Tensor>> {
        let b = self.drawn.len();
        Ok((!rows.is_empty()).then(|| Tensor::from_vec(rows.to_vec(), (b, rows.len() / b), &Device::Cpu)).transpose()?)
    }
}

/// The share of GloGen's training windows that aim at a target, and of those whose target
/// pins its root too: the rest teach the block to move freely, as between far keys.
const TARGET_SHARE: f32 = 0.6;
const ROOT_TARGET_SHARE: f32 = 0.5;

/// Mean distances of predicted poses (`predictions`, one normalised window each) and of the
/// baselines to the real poses.
fn position_errors<'a>(norm: &Normalizer, layout: &FeatureLayout, windows: &[ValWindow], predictions: impl Iterator<Item = &'a [f32]>) -> (f32, f32) {
    let decoded = windows.iter().zip(predictions).map(|(w, p)| {
        let mut p = p.to_vec();
        norm.denormalize(&mut p);
        layout.decode(&p, w.start).0
    });
    frame_errors(windows, decoded)
}

/// Mean distances of each window's predicted frames (`predicted`, one list each) and of its
/// baseline to the real frames.
pub(super) fn frame_errors(windows: &[ValWindow], predicted: impl Iterator<Item = Vec<Vec3>>) -> (f32, f32) {
    let (mut err, mut base, mut count) = (0.0f64, 0.0f64, 0usize);
    for (w, positions) in windows.iter().zip(predicted) {
        for ((a, b), c) in positions.iter().zip(&w.target_positions).zip(&w.baseline_positions) {
            err += a.distance(*b) as f64;
            base += c.distance(*b) as f64;
            count += 1;
        }
    }
    if count == 0 {
        return (f32::NAN, f32::NAN);
    }
    ((err / count as f64) as f32, (base / count as f64) as f32)
}

/// GloGen: blocks of sparse poses, rolled out on its own outputs for `rollout_blocks` blocks.
pub(super) struct GloGenTraining<'a>(pub TrainingData<'a>);

impl GloGenTraining<'_> {
    /// `1 + blocks` blocks of sparse poses from `frame`: (the first block, the rest), normalised.
    fn window(&self, track: &Track, frame: usize, blocks: usize) -> (Vec<f32>, Vec<f32>) {
        let data = &self.0;
        let t = data.spec.block_len;
        let mut all = data.layout().encode_motion(&track.motion, frame, data.spec.stride, t * (1 + blocks));
        data.norm.normalize(&mut all);
        let split = t * data.layout().dim();
        (all[..split].to_vec(), all[split..].to_vec())
    }

    /// The conditioning of each of the rollout's `blocks` blocks: the window's class, and for
    /// a target-conditioned GloGen a real pose of the clip ahead as its target, for every
    /// block until the one that reaches it (a share of windows has none).
    fn block_conds(&self, batch: &Batch<'_>, blocks: usize, rng: &mut StdRng) -> Result<Vec<Option<Tensor>>> {
        let data = &self.0;
        if !data.spec.glogen.target {
            let cond = batch.cond(&batch.conds)?;
            return Ok(vec![cond; blocks]);
        }
        let (t, s, dim) = (data.spec.block_len, data.spec.stride, data.layout().dim());
        let cond_dim = batch.conds.len() / batch.drawn.len();
        let class_len = cond_dim - target_len(dim);
        let mut rows = vec![batch.conds.clone(); blocks];
        for (i, &(track, frame)) in batch.drawn.iter().enumerate() {
            if rng.random::<f32>() >= TARGET_SHARE {
                continue;
            }
            // The target's index among the poses after the context, and whether it pins its root.
            let k = rng.random_range(0..(blocks + 1) * t);
            let fix_root = rng.random::<f32>() < ROOT_TARGET_SHARE;
            let pose = track.motion.frame(frame + (t + k) * s);
            for (r, row) in rows.iter_mut().enumerate() {
                let Some(steps) = (k + 1).checked_sub(r * t).filter(|&n| n > 0) else { continue };
                let from = data.layout().placement(track.motion.frame(frame + (t + r * t - 1) * s));
                let target = Target { pose, steps: steps as f32, fix_root };
                let condition = target_condition(data.layout(), data.norm, t, from, Some(target));
                row[i * cond_dim + class_len..(i + 1) * cond_dim].copy_from_slice(&condition);
            }
        }
        rows.iter().map(|row| batch.cond(row)).collect()
    }

    /// `[B, 1, 1]`: 1 for each window of `cond` `[B, cond_dim]` without a target, 0 for those
    /// on their way to one.
    fn free_rows(&self, cond: &Tensor) -> Result<Tensor> {
        let spec = self.0.spec;
        let flag = spec.label_len() + target_flag(self.0.layout().dim());
        Ok(cond.narrow(1, flag, 1)?.affine(-1.0, 1.0)?.unsqueeze(2)?)
    }

    /// A block from `input` `[B, T, dim]`, as [`GloGen::block`] makes it: a window with a
    /// target is an offset from the straight way to it, else a residual GloGen's is an offset
    /// from (a share of) the input's last pose.
    fn predict(&self, block: &Seq2SeqBlock, input: &Tensor, cond: Option<&Tensor>) -> Result<Tensor> {
        let spec = self.0.spec;
        let pred = block.forward(input, cond, true)?;
        let last = input.narrow(1, input.dim(1)? - 1, 1)?;
        let free = match spec.glogen.base_weights(spec.block_len) {
            Some(w) => {
                let w = Tensor::from_vec(w, (1, spec.block_len, 1), pred.device())?;
                pred.broadcast_add(&last.broadcast_mul(&w)?)?
            }
            None => pred.clone(),
        };
        let Some(cond) = cond.filter(|_| spec.glogen.target) else { return Ok(free) };
        let (t, dim) = (spec.block_len, self.0.layout().dim());
        let class_len = spec.label_len();
        let rows = cond.to_vec2::<f32>()?;
        // Per window, the way's ends and shares and whether it has one at all.
        let (mut ends, mut shares, mut has) = (Vec::new(), Vec::new(), Vec::new());
        for row in &rows {
            let way = Way::to(&row[class_len..], dim, t, self.0.norm);
            has.push(if way.is_some() { 1.0f32 } else { 0.0 });
            let way = way.unwrap_or_else(|| Way { shares: vec![0.0; t * dim], ends: vec![0.0; t * dim] });
            ends.extend(way.ends);
            shares.extend(way.shares);
        }
        let b = rows.len();
        let ends = Tensor::from_vec(ends, (b, t, dim), &Device::Cpu)?;
        let shares = Tensor::from_vec(shares, (b, t, dim), &Device::Cpu)?;
        let has = Tensor::from_vec(has, (b, 1, 1), &Device::Cpu)?;
        let way = last.broadcast_add(&shares.mul(&ends.broadcast_sub(&last)?)?)?;
        let aimed = pred.add(&way)?.broadcast_mul(&has)?;
        Ok((aimed + free.broadcast_mul(&has.affine(-1.0, 1.0)?)?)?)
    }
}

impl StageTraining for GloGenTraining<'_> {
    fn loss(&self, block: &Seq2SeqBlock, rng: &mut StdRng) -> Result<Tensor> {
        let spec = &self.0.spec.glogen;
        let (blocks, t) = (spec.rollout_blocks, self.0.spec.block_len);
        // A target-conditioned GloGen's targets may lie a block past the rollout.
        let ahead = blocks + usize::from(spec.target);
        let span = self.0.spec.stride * t * (1 + ahead);
        let batch = self.0.batch(block, span, ahead, rng, |track, frame| self.window(track, frame, ahead))?;
        let (x, steps_in) = (&batch.x, batch.x.dim(1)?);
        let y = batch.y.narrow(1, 0, blocks * steps_in)?;
        let conds = self.block_conds(&batch, blocks, rng)?;
        // Every block of the rollout, as generation leaves it: joined onto the block before,
        // which a two-sided join moves in turn (the observed context stays). This is the
        // rollout of `model::rollout` as differentiable tensor operations.
        let mut preds: Vec<Tensor> = Vec::with_capacity(blocks);
        let mut input = x.clone();
        for cond in &conds {
            let mut pred = self.predict(block, &input, cond.as_ref())?;
            if spec.joined {
                let before = match preds.last() {
                    Some(previous) => previous.clone(),
                    None => input.narrow(1, steps_in - 1, 1)?,
                };
                let steps = match (spec.target, cond) {
                    (true, Some(cond)) => Some(self.free_rows(cond)?),
                    _ => None,
                };
                let (before, joined) = join_seams_tensor(&before, &pred, spec.seam_join, steps.as_ref())?;
                if let Some(previous) = preds.last_mut() {
                    *previous = before;
                }
                pred = joined;
            }
            input = pred.clone();
            preds.push(pred);
        }
        let mut total: Option<Tensor> = None;
        for (r, pred) in preds.iter().enumerate() {
            let target = y.narrow(1, r * steps_in, steps_in)?;
            let last = if r == 0 { x.narrow(1, steps_in - 1, 1)? } else { preds[r - 1].narrow(1, steps_in - 1, 1)? };
            let l = joint_flow_loss(pred, &target, Some(&last), spec.loss)?;
            total = Some(match total {
                Some(t) => (t + l)?,
                None => l,
            });
        }
        Ok((total.expect("at least one block") / blocks as f64)?)
    }

    fn validation_windows(&self) -> Vec<ValWindow> {
        let data = &self.0;
        let (s, t) = (data.spec.stride, data.spec.block_len);
        data.held_out(s * 2 * t, |track, frame| {
            let m = &track.motion;
            let (input, _) = self.window(track, frame, 1);
            let first_out = frame + t * s;
            let last_in = m.frame(first_out - s);
            let target_positions = (0..t).flat_map(|k| m.frame(first_out + k * s).to_vec()).collect();
            let baseline_positions = (0..t).flat_map(|_| last_in.to_vec()).collect();
            ValWindow { input, class: track.class, style: track.style, target_positions, start: data.layout().placement(last_in), baseline_positions }
        })
    }

    /// One block rolled out from each window by generation's own rollout, on the block's
    /// weights as they are now.
    fn validate(&self, block: &Seq2SeqBlock, windows: &[ValWindow]) -> Result<(f32, f32)> {
        let data = &self.0;
        let glogen = GloGen::new(block.freeze()?, data.spec);
        let mut ws = BlockWorkspace::default();
        let mut predictions = Vec::with_capacity(windows.len());
        for w in windows {
            let mut sparse = w.input.clone();
            let mut class = vec![0.0; block.cfg.cond_dim];
            if data.spec.glogen.use_class {
                data.spec.set_labels(&mut class, w.class, w.style);
            }
            rollout(&glogen, &mut ws, &mut sparse, 1, data.spec.glogen.joined, &mut OneClass(class))?;
            predictions.push(sparse.split_off(w.input.len()));
        }
        Ok(position_errors(data.norm, data.layout(), windows, predictions.iter().map(Vec::as_slice)))
    }
}

/// LocGen: the residual on a dense window interpolated between the sparse poses.
pub(super) struct LocGenTraining<'a>(pub TrainingData<'a>);

impl LocGenTraining<'_> {
    /// The interpolated window from `frame` and the real one, normalised.
    fn window(&self, track: &Track, frame: usize) -> (Vec<f32>, Vec<f32>) {
        let data = &self.0;
        let (m, s, w) = (&track.motion, data.spec.stride, data.spec.locgen.window);
        let interp = interpolated_window(m, frame, w, s, data.spec.locgen.interpolation);
        let frames: Vec<&[Vec3]> = interp.chunks_exact(m.joints()).collect();
        let mut input = data.layout().encode(&frames, Some(m.frame(frame - 1)));
        let mut target = data.layout().encode_motion(m, frame, 1, w);
        data.norm.normalize(&mut input);
        data.norm.normalize(&mut target);
        (input, target)
    }

    /// The refined window: LocGen predicts a residual on its interpolated input, in units of
    /// the residual's spread.
    fn predict(&self, block: &Seq2SeqBlock, input: &Tensor, train: bool) -> Result<Tensor> {
        let spec = self.0.spec;
        let gain = Tensor::from_vec(spec.locgen_gain(), (1, spec.locgen.window, block.cfg.out_dim), &Device::Cpu)?;
        Ok((block.forward(input, None, train)?.broadcast_mul(&gain)? + input)?)
    }
}

/// Per feature, the root mean square of the real frames about their interpolation over
/// training windows (normalised units): LocGen's [`LocGenSpec::residual_scale`].
///
/// [`LocGenSpec::residual_scale`]: crate::model::spec::LocGenSpec
pub(super) fn locgen_residual_scale(data: TrainingData) -> Result<Vec<f32>> {
    const WINDOWS: usize = 4096;
    let training = LocGenTraining(data);
    let data = &training.0;
    let (dim, span) = (data.layout().dim(), data.spec.locgen.window + 1);
    let mut rng = StdRng::seed_from_u64(0x5CA1E);
    let mut spread = ResidualSpread::new(dim);
    for _ in 0..WINDOWS {
        let (track, start) = sample_window(&data.corpus.train, data.corpus.classes.len(), span + data.spec.stride, &mut rng).context("no training clip is long enough")?;
        let (input, target) = training.window(track, start + data.spec.stride);
        input.chunks_exact(dim).zip(target.chunks_exact(dim)).for_each(|(i, t)| spread.add(i, t));
    }
    // The body's travel and turn stay the interpolation's: a residual on a step is summed
    // over the window and turns every joint about the root, where one on a joint moves that
    // joint alone.
    Ok(spread.scale(|i| (1..ROOT_FEATURES).contains(&i)))
}

/// Per feature, the spread of real frames about the frames a stage refines: the root mean
/// square of their difference over the rows added.
pub(super) struct ResidualSpread {
    sums: Vec<f64>,
    rows: usize,
}

impl ResidualSpread {
    pub fn new(dim: usize) -> Self {
        Self { sums: vec![0.0; dim], rows: 0 }
    }

    /// One frame: the stage's input (its first `dim` values are the features) and the real
    /// frame's features.
    pub fn add(&mut self, input: &[f32], real: &[f32]) {
        self.sums.iter_mut().zip(input.iter().zip(real)).for_each(|(s, (a, b))| *s += f64::from(b - a).powi(2));
        self.rows += 1;
    }

    /// The spread per feature, 0 where `fixed` (a feature the stage leaves as it is), and no
    /// less than 1e-4 elsewhere (a feature the interpolation always gets right stays
    /// scalable).
    pub fn scale(&self, fixed: impl Fn(usize) -> bool) -> Vec<f32> {
        let rms = |s: f64| ((s / self.rows.max(1) as f64).sqrt() as f32).max(1e-4);
        self.sums.iter().enumerate().map(|(i, &s)| if fixed(i) { 0.0 } else { rms(s) }).collect()
    }
}

/// The joint and flow loss of `pred` against `target` (normalised features), each feature
/// weighed back to the skeleton's units: in normalised features a hand's residual counted a
/// fraction of the same distance at the hips, the opposite of what shows.
pub(super) fn skeleton_weighted_loss(norm: &Normalizer, pred: &Tensor, target: &Tensor) -> Result<Tensor> {
    let std = &norm.std;
    let rms = (std.iter().map(|s| s * s).sum::<f32>() / std.len() as f32).sqrt();
    let weight = Tensor::from_vec(std.iter().map(|s| s / rms).collect(), (1, 1, std.len()), &Device::Cpu)?;
    Ok(joint_flow_loss(&pred.broadcast_mul(&weight)?, &target.broadcast_mul(&weight)?, None, LossKind::JointFlow)?)
}

impl StageTraining for LocGenTraining<'_> {
    fn loss(&self, block: &Seq2SeqBlock, rng: &mut StdRng) -> Result<Tensor> {
        let span = self.0.spec.locgen.window + 1;
        let batch = self.0.batch(block, span, 1, rng, |track, frame| self.window(track, frame))?;
        let pred = self.predict(block, &batch.x, true)?;
        skeleton_weighted_loss(self.0.norm, &pred, &batch.y)
    }

    fn validation_windows(&self) -> Vec<ValWindow> {
        let data = &self.0;
        let (s, w) = (data.spec.stride, data.spec.locgen.window);
        data.held_out(w + 1, |track, frame| {
            let m = &track.motion;
            let (input, _) = self.window(track, frame);
            let target_positions = (0..w).flat_map(|k| m.frame(frame + k).to_vec()).collect();
            let baseline_positions = interpolated_window(m, frame, w, s, data.spec.locgen.interpolation);
            ValWindow { input, class: track.class, style: track.style, target_positions, start: data.layout().placement(m.frame(frame - 1)), baseline_positions }
        })
    }

    fn validate(&self, block: &Seq2SeqBlock, windows: &[ValWindow]) -> Result<(f32, f32)> {
        let Some(first) = windows.first() else { return Ok((f32::NAN, f32::NAN)) };
        let data = &self.0;
        let dim = data.layout().dim();
        let steps = first.input.len() / dim;
        let x: Vec<f32> = windows.iter().flat_map(|w| w.input.iter().copied()).collect();
        let x = Tensor::from_vec(x, (windows.len(), steps, dim), &Device::Cpu)?;
        let pred = self.predict(block, &x, false)?.flatten_all()?.to_vec1::<f32>()?;
        Ok(position_errors(data.norm, data.layout(), windows, pred.chunks_exact(steps * dim)))
    }
}
