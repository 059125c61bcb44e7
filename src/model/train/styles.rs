//! Teaching a trained GloGen styles by their label inputs alone (`--only-styles`): the
//! columns of those styles in every tensor that reads the conditioning are the only weights
//! that train, from zero, on the clips of those styles. A style's input is zero in every take
//! made in another style, so each of those takes, and every class figure made without the
//! new styles, stays exactly as it was. This is how `models/all` learned Bandai's test styles
//! (tired, musical) from the test clips that teach them, without training again on the rest.

use anyhow::{bail, Context, Result};
use candle_core::{Device, Tensor, Var};
use candle_nn::VarMap;

use super::widen::carries_cond;
use crate::model::block::BlockConfig;
use crate::model::corpus::{Corpus, Track};
use crate::model::spec::ModelSpec;

/// The indices in `corpus.styles` of the styles `names` asks for, checked before anything is
/// written.
pub(super) fn style_indices(corpus: &Corpus, names: &[String]) -> Result<Vec<usize>> {
    if corpus.styles.is_empty() && !names.is_empty() {
        bail!("--only-styles: the {} data has no styles", corpus.dataset);
    }
    names
        .iter()
        .map(|n| corpus.style_index(n).with_context(|| format!("--only-styles: '{n}' is not a style of the data ({})", corpus.styles.join(", "))))
        .collect()
}

/// The clips of `styles` (indices into `corpus.styles`): those they are learned from to
/// train on, and the test clips that do not teach them to validate on.
pub(super) fn style_corpus(corpus: &Corpus, styles: &[usize]) -> Result<Corpus> {
    let of_styles = |t: &&Track| t.style.is_some_and(|s| styles.contains(&s));
    let train: Vec<Track> = corpus.style_training().filter(of_styles).cloned().collect();
    if train.is_empty() {
        bail!("--only-styles: the data has no clip of {} to learn from", styles.iter().map(|&s| corpus.styles[s].as_str()).collect::<Vec<_>>().join(", "));
    }
    let test = corpus.test.iter().filter(of_styles).filter(|t| !t.teaches_style).cloned().collect();
    Ok(corpus.with_tracks(train, test))
}

/// The tensors that read the styles' inputs, each with the values of its other columns
/// (the styles' zeroed) and a row mask of the styles' columns.
pub(super) struct StyleInputs {
    tensors: Vec<(Var, Tensor, Tensor)>,
}

impl StyleInputs {
    /// The label inputs of `styles` (indices into `spec.styles`) in the block of `cfg` held
    /// by `varmap`, zeroed first unless a resumed run continues them. Returns them and the
    /// variables the optimiser trains.
    pub(super) fn new(varmap: &VarMap, cfg: &BlockConfig, spec: &ModelSpec, styles: &[usize], zero: bool) -> Result<(Self, Vec<(String, Var)>)> {
        let vars = varmap.data().lock().map_err(|_| anyhow::anyhow!("variable map poisoned"))?;
        let (mut tensors, mut trained) = (Vec::new(), Vec::new());
        for (name, var) in vars.iter().filter(|(name, _)| carries_cond(name, cfg)) {
            let width = var.dims()[1];
            let cond_start = width - cfg.cond_dim;
            let mut mask = vec![0f32; width];
            // A style's entry comes after every class's ([`ModelSpec::label_indices`]).
            for &s in styles {
                mask[cond_start + spec.classes.len() + s] = 1.0;
            }
            let mask = Tensor::from_vec(mask, (1, width), &Device::Cpu)?;
            let others = var.as_tensor().broadcast_mul(&(1.0 - &mask)?)?;
            if zero {
                var.set(&others)?;
            }
            tensors.push((var.clone(), others, mask));
            trained.push((name.clone(), var.clone()));
        }
        if tensors.is_empty() {
            bail!("--only-styles: the GloGen reads no labels");
        }
        Ok((Self { tensors }, trained))
    }

    /// Puts every weight but the styles' back to what it was (an optimiser step moves all of
    /// a tensor: its decay and its moments reach every column).
    pub(super) fn restore(&self) -> Result<()> {
        for (var, others, mask) in &self.tensors {
            var.set(&(others + var.as_tensor().broadcast_mul(mask)?)?)?;
        }
        Ok(())
    }
}
