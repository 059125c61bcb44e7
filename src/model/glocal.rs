//! A trained GlocalNet loaded for generation: GloGen and LocGen frozen to plain f32, the
//! model description and the seed bank.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use candle_core::{DType, Device};
use candle_nn::{VarBuilder, VarMap};
use glam::Vec3;

use super::block::{BlockConfig, BlockWorkspace, FrozenBlock, Seq2SeqBlock};
use super::corpus::interpolated_window;
use super::glogen::GloGen;
use super::rollout::{rollout, OneClass};
use super::inbetween::{fill_frames, gap_gain, gap_window};
use super::spec::{InbetweenSpec, ModelSpec, Seed, GAP_CHANNELS, GLOGEN_FILE, INBETWEEN_FILE, LOCGEN_FILE};
use super::texture::{Texture, TEXTURE_FILE};
use super::Error;
use crate::data::features::{interpolate, Placement};
use crate::data::input::read_text;
use crate::motion::{floor_height, Motion};

pub const SEEDS_FILE: &str = "seeds.json";

/// A seed bank larger than this is not one (the shipped ones are about 1 MB).
const MAX_SEEDS_BYTES: u64 = 256 << 20;

/// The largest magnitude a seed's feature may have: a kilometre in millimetres, far beyond
/// any pose, and far from where squaring or summing features overflows f32.
const MAX_SEED_FEATURE: f32 = 1e6;

/// LocGen windows per batch: 256 windows (102 s at 25 fps) keep its workspace near 20 MB.
const LOCGEN_CHUNK: usize = 256;

pub struct GlocalModel {
    pub dir: PathBuf,
    pub spec: ModelSpec,
    pub seeds: Vec<Seed>,
    glogen: GloGen,
    locgen: Option<FrozenBlock>,
    inbetween: Option<FrozenBlock>,
    texture: Option<Texture>,
}

impl GlocalModel {
    /// Loads a model folder; every file is checked, and a missing or mismatched one is an
    /// error that names it. A folder without LocGen still generates (plain interpolation).
    pub fn load(dir: &Path) -> Result<Self, Error> {
        let spec = ModelSpec::read_verified(dir)?;
        let glogen = GloGen::new(load_block(&dir.join(GLOGEN_FILE), &spec.glogen.block)?.freeze()?, &spec);
        let locgen_path = dir.join(LOCGEN_FILE);
        let locgen = if locgen_path.exists() { Some(load_block(&locgen_path, &spec.locgen.block)?.freeze()?) } else { None };
        let inbetween_path = dir.join(INBETWEEN_FILE);
        let inbetween = match &spec.inbetween {
            Some(s) if inbetween_path.exists() => Some(load_block(&inbetween_path, &s.block)?.freeze()?),
            _ => None,
        };
        let seeds = read_seed_bank(&dir.join(SEEDS_FILE), &spec)?;
        let texture_path = dir.join(TEXTURE_FILE);
        let texture = if texture_path.exists() { Some(Texture::load(&texture_path, &spec)?) } else { None };
        Ok(Self { dir: dir.to_path_buf(), spec, seeds, glogen, locgen, inbetween, texture })
    }

    /// The model with its guidance steering each class named away from its pair
    /// ([`ModelSpec::class_contrasts`]); an unknown class or a model without guidance is
    /// refused, the model unchanged.
    pub fn with_class_contrasts(self, contrasts: BTreeMap<String, String>) -> Result<Self, Error> {
        let mut model = self.with_spec(|spec| spec.class_contrasts = contrasts)?;
        model.glogen.set_contrasts(&model.spec);
        Ok(model)
    }

    /// The model with `edit` made to its spec; an edit that leaves the spec invalid is refused
    /// naming the field, the model unchanged.
    fn with_spec(mut self, edit: impl FnOnce(&mut ModelSpec)) -> Result<Self, Error> {
        let mut spec = self.spec.clone();
        edit(&mut spec);
        spec.validate().map_err(|problem| Error::SpecInvalid { name: self.dir.join("model.json").display().to_string(), problem })?;
        self.spec = spec;
        Ok(self)
    }

    /// The motion texture of the model's classes, if its folder has one.
    pub fn texture(&self) -> Option<&Texture> {
        self.texture.as_ref()
    }

    /// The model with each class's share of its texture as `gains` gives it
    /// ([`ModelSpec::texture_gains`]); a gain out of range or of an unknown class is refused.
    pub fn with_texture_gains(self, gains: BTreeMap<String, f32>) -> Result<Self, Error> {
        self.with_spec(|spec| spec.texture_gains = gains)
    }

    /// The model with its bones' turn limits replaced
    /// ([`ModelSpec::bone_turn_limits`]).
    pub fn with_bone_turn_limits(self, limits: BTreeMap<String, f32>) -> Result<Self, Error> {
        self.with_spec(|spec| spec.bone_turn_limits = limits)
    }

    /// The model with each style's speed replaced ([`ModelSpec::style_speed`]).
    pub fn with_style_speeds(self, speeds: BTreeMap<String, BTreeMap<String, f32>>) -> Result<Self, Error> {
        self.with_spec(|spec| spec.style_speed = speeds)
    }

    pub fn has_locgen(&self) -> bool {
        self.locgen.is_some()
    }

    /// The height of the floor in the model's world: the mean over the seed bank of each
    /// window's lowest joint.
    pub fn floor_height(&self) -> f32 {
        let layout = &self.spec.layout;
        let lowest = |s: &Seed| floor_height(&layout.decode(&s.features, Placement::default()).0);
        self.seeds.iter().map(lowest).sum::<f32>() / self.seeds.len().max(1) as f32
    }

    /// The `variant`-th seed-bank window of `class` (wrapping around), if the class has any.
    pub fn seed_of_class(&self, class: usize, variant: usize) -> Option<&Seed> {
        self.seeds.iter().filter(|s| s.class == class).nth(self.class_seed_index(class, variant)?)
    }

    /// Which of `class`'s seed-bank windows (counted in seed-bank order) its `variant`-th is,
    /// wrapping around, if the class has any.
    pub fn class_seed_index(&self, class: usize, variant: usize) -> Option<usize> {
        let count = self.seeds.iter().filter(|s| s.class == class).count();
        (count > 0).then(|| variant % count)
    }

    /// The first of `class`'s seed-bank windows in `style` as its variant (counted as
    /// [`Self::class_seed_index`] counts), if the class has one.
    pub fn class_seed_variant_in_style(&self, class: usize, style: usize) -> Option<usize> {
        self.seeds.iter().filter(|s| s.class == class).position(|s| s.style == Some(style))
    }

    /// The conditioning vector of `class`, in its usual style on a model with styles (whose
    /// GloGen never saw a class without one); all zeros when the model was trained without
    /// classes.
    pub fn class_vector(&self, class: usize) -> Vec<f32> {
        let mut v = vec![0.0; self.spec.glogen.block.cond_dim];
        if self.spec.glogen.use_class && class < self.spec.classes.len() {
            self.spec.set_labels(&mut v, class, self.spec.usual_styles.get(class).copied());
        }
        v
    }

    /// GloGen, frozen: blocks, their seam join and the rollout's step.
    pub fn glogen(&self) -> &GloGen {
        &self.glogen
    }

    /// GloGen's encoder states over one block, concatenated: the embedding of the t-SNE panel.
    pub fn embed(&self, input: &[f32], class: &[f32]) -> Vec<f32> {
        self.glogen.embed(input, class)
    }

    /// LocGen over `windows` windows of normalised interpolated dense features, in place:
    /// LocGen predicts a residual on the interpolation, in units of its spread. Returns false
    /// without LocGen.
    pub fn locgen(&self, frames: &mut [f32], windows: usize) -> bool {
        let Some(locgen) = self.locgen.as_ref() else { return false };
        let (w, dim) = (self.spec.locgen.window, self.spec.layout.dim());
        let width = w * dim;
        let gain = self.spec.locgen_gain();
        // Chunks of windows bound the workspace (gates and states of every window in the
        // batch) whatever the take's length.
        let mut residual = vec![0.0; LOCGEN_CHUNK.min(windows) * width];
        let mut ws = BlockWorkspace::default();
        for chunk in frames[..windows * width].chunks_mut(LOCGEN_CHUNK * width) {
            let n = chunk.len() / width;
            locgen.infer(&mut ws, chunk, None, n, w, &mut residual[..n * width]);
            for (window, res) in chunk.chunks_exact_mut(width).zip(residual.chunks_exact(width)) {
                window.iter_mut().zip(res.iter().zip(&gain)).for_each(|(f, (r, g))| *f += r * g);
            }
        }
        true
    }
}

impl GlocalModel {
    /// The in-betweener's shape (its reach and the known frames it reads either side of a
    /// gap); None without one.
    pub fn inbetween(&self) -> Option<&InbetweenSpec> {
        self.inbetween.as_ref()?;
        self.spec.inbetween.as_ref()
    }

    /// The `gap` frames between the known frames `context` (the frame `before` them starts
    /// their velocities) and `ahead`, the key after the gap and up to
    /// [`InbetweenSpec::after`] known frames after it, in their world: their linear
    /// interpolation with the in-betweener's residual; the body arrives where the key stands.
    /// None without an in-betweener, or for a gap or context it was not trained for.
    pub fn fill_gap(&self, before: &[Vec3], context: &[Vec3], ahead: &[Vec3], gap: usize) -> Option<Vec<Vec3>> {
        let (block, spec) = (self.inbetween.as_ref()?, self.spec.inbetween.as_ref()?);
        let (layout, norm) = (&self.spec.layout, &self.spec.dense_norm);
        let (j, dim) = (layout.joints(), layout.dim());
        let known_after = ahead.len() / j;
        if gap == 0 || gap > spec.max_gap || context.len() != spec.context * j || !(1..=spec.after + 1).contains(&known_after) {
            return None;
        }
        let (input, _) = gap_window(layout, norm, before, context, ahead, gap);
        let frames = spec.context + gap + known_after;
        let mut residual = vec![0.0; frames * dim];
        block.infer(&mut BlockWorkspace::default(), &input, None, 1, frames, &mut residual);
        let mut feats: Vec<f32> = input.chunks_exact(dim + GAP_CHANNELS).flat_map(|row| row[..dim].iter().copied()).collect();
        feats.iter_mut().zip(residual.iter().zip(gap_gain(spec, gap, frames))).for_each(|(f, (r, g))| *f += r * g);
        let positions = fill_frames(layout, norm, feats, layout.placement(before), spec.context, gap, ahead[0]);
        Some(positions[spec.context * j..(spec.context + gap) * j].to_vec())
    }

    /// GloGen continuing real motion: `blocks * block_len` sparse poses after frame `t0` of
    /// `m` (on the model's skeleton and frame rate), the `k`-th at frame `t0 + (k + 1) *
    /// stride`, rolled out block by block by [`rollout`] from the `block_len`
    /// observed sparse poses ending at `t0`. Positions are in the motion's own world frame.
    pub fn forecast(&self, m: &Motion, t0: usize, class: usize, blocks: usize, join_seams: bool) -> Result<Vec<Vec3>> {
        let (s, t, dim) = (self.spec.stride, self.spec.block_len, self.spec.layout.dim());
        let first = t0 as isize - self.spec.observed_span() as isize;
        if first < s as isize || t0 >= m.frames() {
            bail!("frame {t0} has too little observed motion before it for the model ({} frames needed)", t * s);
        }
        let mut sparse = self.spec.layout.encode_motion(m, first as usize, s, t);
        self.spec.sparse_norm.normalize(&mut sparse);
        // The observed poses stay where they were observed: the join sees their last alone.
        rollout(&self.glogen, &mut BlockWorkspace::default(), &mut sparse, blocks, join_seams, &mut OneClass(self.class_vector(class)))?;
        let mut predicted = sparse.split_off(t * dim);
        self.spec.sparse_norm.denormalize(&mut predicted);
        Ok(self.spec.layout.decode(&predicted, self.spec.layout.placement(m.frame(t0))).0)
    }

    /// The model's interpolation of the true sparse keyframes of `m` over the LocGen window
    /// that starts at frame `start` (what LocGen refines).
    pub fn keyframe_window(&self, m: &Motion, start: usize) -> Vec<Vec3> {
        interpolated_window(m, start, self.spec.locgen.window, self.spec.stride, self.spec.locgen.interpolation)
    }

    /// LocGen over whole windows of interpolated dense poses, each given with the pose just
    /// before it (which places it and starts its velocities); the refined poses, window after
    /// window. None without LocGen.
    pub fn refine_windows(&self, windows: &[(&[Vec3], &[Vec3])]) -> Option<Vec<Vec3>> {
        if !self.has_locgen() {
            return None;
        }
        let (layout, norm) = (self.spec.layout.clone(), self.spec.dense_norm.clone());
        let (j, width) = (layout.joints(), self.spec.locgen.window * layout.dim());
        let mut feats = Vec::with_capacity(windows.len() * width);
        for (poses, before) in windows {
            let refs: Vec<&[Vec3]> = poses.chunks_exact(j).collect();
            feats.extend(layout.encode(&refs, Some(before)));
        }
        norm.normalize(&mut feats);
        self.locgen(&mut feats, windows.len());
        norm.denormalize(&mut feats);
        Some(feats.chunks_exact(width).zip(windows).flat_map(|(f, (_, before))| layout.decode(f, layout.placement(before)).0).collect())
    }

    /// Dense frames between sparse poses at the model's native stride: their linear
    /// interpolation, refined by LocGen when asked and available.
    pub fn densify(&self, sparse: &[Vec3], refine: bool) -> Vec<Vec3> {
        let spec = &self.spec;
        let j = spec.layout.joints();
        let dense = interpolate(sparse, j, spec.stride, spec.locgen.interpolation);
        if !refine || !self.has_locgen() {
            return dense;
        }
        let (layout, norm, w) = (spec.layout.clone(), spec.dense_norm.clone(), spec.locgen.window);
        let dim = layout.dim();
        let frames = dense.len() / j;
        let windows = frames.div_ceil(w);
        let refs: Vec<&[Vec3]> = dense.chunks_exact(j).collect();
        let mut feats = layout.encode(&refs, None);
        // Pad to whole windows with the last pose standing still, then drop the pad.
        let mut still = feats[feats.len() - dim..].to_vec();
        still[1..4].fill(0.0);
        while feats.len() < windows * w * dim {
            feats.extend_from_slice(&still);
        }
        norm.normalize(&mut feats);
        self.locgen(&mut feats, windows);
        norm.denormalize(&mut feats);
        feats.truncate(frames * dim);
        // The first frame's features carry no displacement, so decoding starts where it stands.
        layout.decode(&feats, layout.placement(refs[0])).0
    }
}

/// The seed bank at `path`, every seed checked against the model: its shape, its class and
/// its values (model.json's checksums cover the weights only, so a damaged seed bank is
/// caught here, before a non-finite pose reaches the generator).
fn read_seed_bank(path: &Path, spec: &ModelSpec) -> Result<Vec<Seed>, Error> {
    let text = read_text(path, MAX_SEEDS_BYTES).map_err(|cause| Error::File { what: format!("model folder has no readable {}", path.display()), cause })?;
    let seeds: Vec<Seed> = serde_json::from_str(&text).map_err(|e| file_error(format!("{} is not a valid seed bank", path.display()), e))?;
    let width = spec.block_len * spec.layout.dim();
    let mismatch = |problem: String| Error::Mismatch { path: path.to_path_buf(), problem };
    for (k, seed) in seeds.iter().enumerate() {
        if seed.features.len() != width || seed.class >= spec.classes.len() || seed.style.is_some_and(|s| s >= spec.styles.len()) {
            return Err(mismatch(format!("seed {k} does not fit the model ({} sparse poses of {} features, {} classes, {} styles)", spec.block_len, spec.layout.dim(), spec.classes.len(), spec.styles.len())));
        }
        if let Some(i) = seed.features.iter().position(|v| !(v.is_finite() && v.abs() <= MAX_SEED_FEATURE)) {
            return Err(mismatch(format!("seed {k}: feature {i} is {:e}; a seed's features are finite and within ±{MAX_SEED_FEATURE:e}", seed.features[i])));
        }
    }
    Ok(seeds)
}

/// Builds a block and fills it from a safetensors file.
pub fn load_block(path: &Path, cfg: &BlockConfig) -> Result<Seq2SeqBlock, Error> {
    let varmap = VarMap::new();
    let block = Seq2SeqBlock::new(cfg.clone(), VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu))?;
    load_weights(path, &varmap)?;
    Ok(block)
}

/// Fills every variable from a safetensors file after checking that each is there with
/// the right shape and dtype and holds only finite values.
pub fn load_weights(path: &Path, varmap: &VarMap) -> Result<(), Error> {
    let bytes = std::fs::read(path).map_err(|e| file_error(format!("cannot read {}", path.display()), e))?;
    let file = safetensors::SafeTensors::deserialize(&bytes).map_err(|e| file_error(format!("{} is not a safetensors file", path.display()), e))?;
    let vars = varmap.data().lock().expect("no thread panics holding the variable map");
    let mut names: Vec<&String> = vars.keys().collect();
    names.sort();
    let mismatch = |problem: String| Error::Mismatch { path: path.to_path_buf(), problem };
    for name in names {
        let var = &vars[name];
        let view = file.tensor(name).map_err(|e| file_error(format!("{} has no tensor '{name}': it was saved for a different model", path.display()), e))?;
        if view.dtype() != safetensors::Dtype::F32 {
            return Err(mismatch(format!("tensor '{name}' is {:?}, expected F32", view.dtype())));
        }
        if view.shape() != var.dims() {
            return Err(mismatch(format!("tensor '{name}' has shape {:?}, the model needs {:?}", view.shape(), var.dims())));
        }
        let values: Vec<f32> = view.data().chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        if values.iter().any(|v| !v.is_finite()) {
            return Err(mismatch(format!("tensor '{name}' holds NaN or infinite values")));
        }
        var.set(&candle_core::Tensor::from_vec(values, var.shape(), &Device::Cpu)?)?;
    }
    Ok(())
}

fn file_error(what: String, cause: impl std::error::Error + Send + Sync + 'static) -> Error {
    Error::File { what, cause: cause.into() }
}
