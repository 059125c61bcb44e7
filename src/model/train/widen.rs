//! Fine-tuning a stage whose new block reads more conditioning than the trained one: a
//! target after the labels, or styles the trained GloGen did not have. Each conditioning
//! input of the new block takes the trained weights of the input of the same meaning (a
//! class or style of the same name); a new input starts at zero, so training starts from
//! the trained block's very motion.

use std::path::Path;

use anyhow::{bail, Context, Result};
use candle_core::{DType, Device, Tensor};
use candle_nn::VarMap;

use super::Stage;
use crate::model::block::BlockConfig;
use crate::model::glocal::load_weights;
use crate::model::spec::ModelSpec;

/// Fills `varmap`, the block `stage` has in `spec`, from that stage's weights in `dir`,
/// trained as `from` describes.
pub(super) fn load_fine_tuned(dir: &Path, stage: Stage, from: &ModelSpec, spec: &ModelSpec, varmap: &VarMap) -> Result<()> {
    let (from_cond, sources) = match stage {
        Stage::Glogen => (from.glogen.block.cond_dim, cond_sources(from, spec)),
        Stage::Locgen | Stage::Inbetween => (0, Vec::new()),
    };
    let path = dir.join(stage.file());
    let (cfg, _) = stage.block_and_norm(spec);
    load_widened(&path, varmap, &cfg, from_cond, &sources).with_context(|| format!("cannot fine-tune from {}", path.display()))
}

/// For each conditioning input of `to`'s GloGen, the one of `from`'s that has its meaning
/// (None: an input `from` did not read): classes and styles by name, the target's inputs
/// after them in order.
pub(super) fn cond_sources(from: &ModelSpec, to: &ModelSpec) -> Vec<Option<usize>> {
    let labels = |spec: &ModelSpec| spec.glogen.class_len(spec.labels());
    let (from_labels, to_labels) = (labels(from), labels(to));
    let mut sources: Vec<Option<usize>> = Vec::with_capacity(to.glogen.block.cond_dim);
    if to_labels > 0 {
        let read = |found: Option<usize>, offset: usize| found.filter(|_| from_labels > 0).map(|i| offset + i);
        sources.extend(to.classes.iter().map(|c| read(from.classes.iter().position(|f| f == c), 0)));
        sources.extend(to.styles.iter().map(|s| read(from.styles.iter().position(|f| f == s), from.classes.len())));
    }
    let from_target = from.glogen.block.cond_dim - from_labels;
    sources.extend((0..to.glogen.block.cond_dim - to_labels).map(|k| (k < from_target).then_some(from_labels + k)));
    sources
}

/// Fills `varmap` (a block of `cfg`) from a stage's trained weights whose conditioning was
/// `from_cond` inputs wide, the new block's conditioning inputs taken from `sources`
/// ([`cond_sources`]; empty for a block without conditioning). Every other tensor must
/// match as [`load_weights`] checks it.
fn load_widened(path: &Path, varmap: &VarMap, cfg: &BlockConfig, from_cond: usize, sources: &[Option<usize>]) -> Result<()> {
    let identity = sources.len() == from_cond && sources.iter().enumerate().all(|(i, s)| *s == Some(i));
    if identity {
        return Ok(load_weights(path, varmap)?);
    }
    let name = path.display();
    let trained = candle_core::safetensors::load(path, &Device::Cpu).with_context(|| format!("cannot read {name}"))?;
    let vars = varmap.data().lock().map_err(|_| anyhow::anyhow!("variable map poisoned"))?;
    for (var_name, var) in vars.iter() {
        let t = trained.get(var_name).with_context(|| format!("{name} has no tensor '{var_name}'"))?;
        let mismatch = || anyhow::anyhow!("{name}: tensor '{var_name}' has shape {:?}, the model needs {:?}", t.dims(), var.dims());
        if !carries_cond(var_name, cfg) {
            if t.dims() != var.dims() {
                return Err(mismatch());
            }
            var.set(t)?;
            continue;
        }
        let (&[rows, new_in], &[trained_rows, trained_in]) = (var.dims(), t.dims()) else { return Err(mismatch()) };
        let prefix = trained_in.checked_sub(from_cond).ok_or_else(mismatch)?;
        if rows != trained_rows || prefix + sources.len() != new_in {
            return Err(mismatch());
        }
        // Column `trained_in` of the padded tensor is zeros, for the new inputs.
        let columns: Vec<u32> = (0..prefix).chain(sources.iter().map(|s| s.map_or(trained_in, |j| prefix + j))).map(|c| c as u32).collect();
        let padded = Tensor::cat(&[t, &Tensor::zeros((rows, 1), DType::F32, &Device::Cpu)?], 1)?;
        var.set(&padded.index_select(&Tensor::new(columns.as_slice(), &Device::Cpu)?, 1)?)?;
    }
    if trained.len() != vars.len() {
        bail!("{name} holds {} tensors, the model has {}", trained.len(), vars.len());
    }
    Ok(())
}

/// Whether a block's tensor reads the conditioning (at the end of its inputs): the encoder's
/// input weights, and the decoder's when it reads the conditioning too.
pub(super) fn carries_cond(var_name: &str, cfg: &BlockConfig) -> bool {
    var_name.contains("weight_ih") && cfg.cond_dim > 0 && (var_name.starts_with("enc.") || (var_name.starts_with("dec.") && cfg.cond_in_decoder))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::target::target_len;

    /// The shipped `all` read as if trained without two of its styles and without a target:
    /// the widened block takes every class's and kept style's weights by name, and the two
    /// styles and the target start from nothing.
    #[test]
    fn conditioning_is_widened_by_name() {
        let to_base = ModelSpec::read(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models/all")).expect("the shipped model");
        let mut to = to_base.clone();
        to.glogen.target = true;
        to.glogen.block.cond_dim += target_len(to.layout.dim());
        let mut from = to_base;
        let dropped = ["giant", "old"];
        from.styles.retain(|s| !dropped.contains(&s.as_str()));
        from.glogen.block.cond_dim -= dropped.len();
        let sources = cond_sources(&from, &to);
        assert_eq!(sources.len(), to.glogen.block.cond_dim);
        let classes = to.classes.len();
        for (i, source) in sources.iter().enumerate() {
            let expected = match i.checked_sub(classes) {
                None => Some(i),
                Some(s) if s < to.styles.len() => from.styles.iter().position(|f| *f == to.styles[s]).map(|j| classes + j),
                Some(_) => None,
            };
            assert_eq!(*source, expected, "input {i}");
        }
        assert_eq!(sources.iter().filter(|s| s.is_none()).count(), dropped.len() + target_len(to.layout.dim()));
    }
}
