//! Training the in-betweener: windows of real motion whose middle frames are hidden, a gap of
//! random length between the known frames before it and the key after it, and the residual
//! on their linear interpolation learnt against the real frames.

use anyhow::{Context, Result};
use candle_core::{Device, Tensor};
use glam::Vec3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::stage::{frame_errors, skeleton_weighted_loss, ResidualSpread, StageTraining, TrainingData, ValWindow};
use crate::model::block::Seq2SeqBlock;
use crate::model::corpus::{sample_window, Track};
use crate::model::inbetween::{bend_ends, fill_frames, gap_gain, gap_window, BEND_SECONDS};
use crate::model::spec::{InbetweenSpec, GAP_CHANNELS};

/// The root feature of the heading's change since the frame before.
const TURN_FEATURE: usize = 3;

/// The gaps validation scores, in seconds (LaFAN1's shortest, about 6 frames, and two longer).
const VALIDATION_GAPS_SECONDS: [f32; 3] = [0.2, 1.0, 2.0];

pub(super) struct InbetweenTraining<'a>(pub TrainingData<'a>);

impl InbetweenTraining<'_> {
    fn spec(&self) -> &InbetweenSpec {
        self.0.spec.inbetween.as_ref().expect("the in-betweener's shape is set before it trains")
    }

    /// The window from `frame` with a gap of `gap` frames and `after` known frames after the
    /// key: its input, the real frames' normalised features, and the real and the
    /// interpolated frames.
    fn window(&self, track: &Track, frame: usize, gap: usize, after: usize) -> (Vec<f32>, Vec<f32>, Vec<Vec3>, Vec<Vec3>) {
        let (data, c) = (&self.0, self.spec().context);
        let m = &track.motion;
        let j = m.joints();
        let frames = c + gap + 1 + after;
        let known = |from: usize, count: usize| -> Vec<Vec3> { (from..from + count).flat_map(|f| m.frame(f).to_vec()).collect() };
        let (context, ahead) = (known(frame, c), known(frame + c + gap, 1 + after));
        let (input, interpolated) = gap_window(data.layout(), data.norm, m.frame(frame - 1), &context, &ahead, gap);
        let mut target = data.layout().encode_motion(m, frame, 1, frames);
        data.norm.normalize(&mut target);
        let real = m.positions()[frame * j..(frame + frames) * j].to_vec();
        (input, target, real, interpolated)
    }

    /// The refined window: the interpolation plus the network's residual, scaled per feature.
    fn predict(&self, block: &Seq2SeqBlock, input: &Tensor, gap: usize, train: bool) -> Result<Tensor> {
        let (frames, dim) = (input.dim(1)?, block.cfg.out_dim);
        let gain = Tensor::from_vec(gap_gain(self.spec(), gap, frames), (1, frames, dim), &Device::Cpu)?;
        let interpolated = input.narrow(2, 0, dim)?;
        Ok((block.forward(input, None, train)?.broadcast_mul(&gain)? + interpolated)?)
    }

    fn gap_of_seconds(&self, seconds: f32) -> usize {
        ((seconds * self.0.spec.fps).round() as usize).clamp(1, self.spec().max_gap)
    }
}

/// A gap of 1 to `max_gap` frames, drawn uniformly on a log scale: a short gap's error is a
/// fraction of a long one's, and drawn evenly the short ones taught the network little (on
/// Bandai its 6-frame fill was 1.5x linear interpolation's error).
fn training_gap(max_gap: usize, rng: &mut StdRng) -> usize {
    let log = rng.random_range(0.0..((max_gap + 1) as f32).ln());
    (log.exp() as usize).clamp(1, max_gap)
}

/// Per feature, the root mean square of the real frames about their linear interpolation over
/// training gaps (normalised units): the in-betweener's [`InbetweenSpec::residual_scale`]. The
/// body's turn stays the straight way's (scale 0): a residual on it would turn every joint
/// after it. Its steps are learnt (a body starting to walk in the gap speeds up where the
/// straight way moves at one speed throughout); generation takes their drift out
/// ([`crate::model::glocal::GlocalModel::fill_gap`]).
pub(super) fn inbetween_residual_scale(data: TrainingData) -> Result<Vec<f32>> {
    const WINDOWS: usize = 2048;
    let training = InbetweenTraining(data);
    let (dim, max_gap, c, after) = (training.0.layout().dim(), training.spec().max_gap, training.spec().context, training.spec().after);
    let mut rng = StdRng::seed_from_u64(0x6A9);
    let mut spread = ResidualSpread::new(dim);
    for _ in 0..WINDOWS {
        let gap = training_gap(max_gap, &mut rng);
        let (track, start) = sample_window(&training.0.corpus.train, training.0.corpus.classes.len(), c + gap + after + 2, &mut rng).context("no training clip is long enough")?;
        let (input, target, _, _) = training.window(track, start + 1, gap, after);
        let gap_rows = input.chunks_exact(dim + GAP_CHANNELS).zip(target.chunks_exact(dim)).skip(c).take(gap);
        gap_rows.for_each(|(i, t)| spread.add(i, t));
    }
    Ok(spread.scale(|i| i == TURN_FEATURE))
}

impl StageTraining for InbetweenTraining<'_> {
    fn loss(&self, block: &Seq2SeqBlock, rng: &mut StdRng) -> Result<Tensor> {
        let data = &self.0;
        let (c, dim, b) = (self.spec().context, data.layout().dim(), data.opts.optimiser.batch);
        // One gap length per batch keeps its windows one tensor; so does one count of frames
        // after the key (a key near the take's end has fewer).
        let gap = training_gap(self.spec().max_gap, rng);
        let after = rng.random_range(0..=self.spec().after);
        let frames = c + gap + 1 + after;
        let (mut xs, mut ys) = (Vec::new(), Vec::new());
        for _ in 0..b {
            let (track, start) = sample_window(&data.corpus.train, data.corpus.classes.len(), frames + 1, rng).context("no training clip is long enough")?;
            let (x, y, _, _) = self.window(track, start + 1, gap, after);
            xs.extend(x);
            ys.extend(y);
        }
        let x = Tensor::from_vec(xs, (b, frames, dim + GAP_CHANNELS), &Device::Cpu)?;
        let y = Tensor::from_vec(ys, (b, frames, dim), &Device::Cpu)?;
        let pred = self.predict(block, &x, gap, true)?;
        skeleton_weighted_loss(data.norm, &pred, &y)
    }

    /// Held-out windows, their gaps taking [`VALIDATION_GAPS_SECONDS`] in turn; the baseline
    /// is linear interpolation.
    fn validation_windows(&self) -> Vec<ValWindow> {
        let gaps: Vec<usize> = VALIDATION_GAPS_SECONDS.iter().map(|&s| self.gap_of_seconds(s)).collect();
        let after = self.spec().after;
        let longest = self.spec().context + gaps.iter().max().copied().unwrap_or(1) + 1 + after;
        let mut k = 0;
        self.0.held_out(longest + 1, |track, frame| {
            let gap = gaps[k % gaps.len()];
            k += 1;
            let (input, _, real, interpolated) = self.window(track, frame, gap, after);
            let start = self.0.layout().placement(track.motion.frame(frame - 1));
            ValWindow { input, class: track.class, style: track.style, target_positions: real, start, baseline_positions: interpolated }
        })
    }

    /// Each window filled as generation fills it: decoded, its arrival at the key spread over
    /// the gap, and its ends bent to the real frames either side.
    fn validate(&self, block: &Seq2SeqBlock, windows: &[ValWindow]) -> Result<(f32, f32)> {
        let (c, after, layout) = (self.spec().context, self.spec().after, self.0.layout());
        let (channels, j) = (layout.dim() + GAP_CHANNELS, layout.joints());
        let mut filled = Vec::with_capacity(windows.len());
        for w in windows {
            let frames = w.input.len() / channels;
            let gap = frames - c - 1 - after;
            let x = Tensor::from_vec(w.input.clone(), (1, frames, channels), &Device::Cpu)?;
            let feats = self.predict(block, &x, gap, false)?.flatten_all()?.to_vec1::<f32>()?;
            let mut window = fill_frames(layout, self.0.norm, feats, w.start, c, gap, w.baseline_positions[(c + gap) * j]);
            bend_ends(&mut window, j, c..c + gap, (BEND_SECONDS * self.0.spec.fps).round() as usize);
            filled.push(window);
        }
        Ok(frame_errors(windows, filled.into_iter()))
    }
}
