//! Training checkpoints: the one state file `--resume` reads (weights, optimiser moments,
//! step and the stage's record), written atomically, and the published weights a model loads.

use std::collections::HashMap;
use std::path::Path;

use anyhow::{bail, Context, Result};
use candle_core::{Device, Tensor};
use candle_nn::VarMap;

use super::TrainOptions;
use crate::data::input::read_bytes;
use crate::data::write::write_atomic;
use crate::model::adamw::AdamW;
use crate::model::glocal::load_weights;
use crate::model::spec::{sha256_hex, ModelSpec, StageRecord};
use crate::motion::clipped;

/// Commits one checkpoint. The training state file is the unit `--resume` reads: weights,
/// optimiser moments, step and the stage's record in one file, renamed into place at once,
/// so a kill at any moment leaves either the previous checkpoint or this one. Only then are
/// the published copies (the weights a model loads, model.json with their checksum) replaced.
pub(super) fn checkpoint(
    varmap: &VarMap,
    opt: &AdamW,
    spec: &mut ModelSpec,
    opts: &TrainOptions,
    record: &StageRecord,
    weights_path: &Path,
    state_path: &Path,
) -> Result<()> {
    let mut tensors = named_tensors(varmap, WEIGHT_PREFIX)?;
    tensors.extend(opt.state_tensors()?.into_iter().map(|(k, v)| (format!("{OPTIMISER_PREFIX}{k}"), v)));
    let metadata = HashMap::from([
        (STEP_KEY.to_string(), opt.step.to_string()),
        (RECORD_KEY.to_string(), serde_json::to_string(record)?),
    ]);
    write_atomic(state_path, &safetensors_bytes(&tensors, Some(metadata), state_path)?)
        .with_context(|| format!("cannot write the training checkpoint {}", state_path.display()))?;
    publish(varmap, spec, opts, record, weights_path)
}

/// Writes the stage's weights and model.json (its record and the weights' checksum).
pub(super) fn publish(varmap: &VarMap, spec: &mut ModelSpec, opts: &TrainOptions, record: &StageRecord, weights_path: &Path) -> Result<()> {
    let bytes = save_weights(varmap, weights_path)?;
    spec.training.weights_sha256.insert(opts.stage.file().to_string(), sha256_hex(&bytes));
    *opts.record_mut(spec) = Some(record.clone());
    spec.write(&opts.out)
}

/// Writes every variable of `varmap` to a safetensors file, atomically; returns its bytes.
pub fn save_weights(varmap: &VarMap, path: &Path) -> Result<Vec<u8>> {
    let bytes = safetensors_bytes(&named_tensors(varmap, "")?, None, path)?;
    write_atomic(path, &bytes).with_context(|| format!("cannot write the weights {}", path.display()))?;
    Ok(bytes)
}

const WEIGHT_PREFIX: &str = "weight.";
const OPTIMISER_PREFIX: &str = "optimiser.";
const STEP_KEY: &str = "step";
const RECORD_KEY: &str = "record";

fn named_tensors(varmap: &VarMap, prefix: &str) -> Result<Vec<(String, Tensor)>> {
    let vars = varmap.data().lock().map_err(|_| anyhow::anyhow!("variable map poisoned"))?;
    Ok(vars.iter().map(|(k, v)| (format!("{prefix}{k}"), v.as_tensor().clone())).collect())
}

fn safetensors_bytes(tensors: &[(String, Tensor)], metadata: Option<HashMap<String, String>>, path: &Path) -> Result<Vec<u8>> {
    let mut data = Vec::with_capacity(tensors.len());
    for (name, t) in tensors {
        let values = t.flatten_all()?.to_vec1::<f32>()?;
        data.push((name.clone(), t.dims().to_vec(), values.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>()));
    }
    let views = data
        .iter()
        .map(|(name, shape, bytes)| Ok((name.as_str(), safetensors::tensor::TensorView::new(safetensors::Dtype::F32, shape.clone(), bytes)?)))
        .collect::<Result<Vec<_>, safetensors::SafeTensorError>>()
        .with_context(|| format!("cannot encode {}", path.display()))?;
    safetensors::serialize(views, metadata).with_context(|| format!("cannot encode {}", path.display()))
}

/// What `--resume` reads back from a training state file.
pub(super) struct Checkpoint {
    pub step: usize,
    pub record: StageRecord,
    pub optimiser: HashMap<String, Tensor>,
}

impl Checkpoint {
    /// Reads the state file and fills `varmap` with its weights; every problem names the file.
    pub fn read(path: &Path, varmap: &VarMap, legacy: Legacy) -> Result<Self> {
        let name = path.display();
        let bytes = read_bytes(path, MAX_CHECKPOINT_BYTES).with_context(|| format!("cannot read the training checkpoint {name}"))?;
        let (_, header) = safetensors::SafeTensors::read_metadata(&bytes).with_context(|| format!("{name} is not a training checkpoint"))?;
        let meta = header.metadata().clone().unwrap_or_default();
        let mut tensors = candle_core::safetensors::load_buffer(&bytes, &Device::Cpu).with_context(|| format!("{name} is not a training checkpoint"))?;
        if let Some((k, _)) = tensors.iter().find(|(_, t)| t.flatten_all().and_then(|t| t.to_vec1::<f32>()).map_or(true, |v| v.iter().any(|x| !x.is_finite()))) {
            bail!("{name}: tensor '{}' is not finite f32 values", clipped(k));
        }
        let (Some(step), Some(record)) = (meta.get(STEP_KEY), meta.get(RECORD_KEY)) else {
            return Self::read_legacy(path, tensors, varmap, legacy);
        };
        let step: usize = step.parse().with_context(|| format!("{name}: step '{}' is not a whole number", clipped(step)))?;
        let record: StageRecord = serde_json::from_str(record).with_context(|| format!("{name}: the stage record is damaged"))?;
        if record.steps != step {
            bail!("{name}: its record says step {}, its optimiser step {step}; the file is damaged", record.steps);
        }
        let vars = varmap.data().lock().map_err(|_| anyhow::anyhow!("variable map poisoned"))?;
        for (var_name, var) in vars.iter() {
            let t = tensors.remove(&format!("{WEIGHT_PREFIX}{var_name}")).with_context(|| format!("{name} has no weights '{var_name}': it was saved for a different model"))?;
            if t.dims() != var.dims() {
                bail!("{name}: weights '{var_name}' have shape {:?}, the model needs {:?}", t.dims(), var.dims());
            }
            var.set(&t).with_context(|| format!("{name}: cannot load '{var_name}'"))?;
        }
        let optimiser = tensors.into_iter().filter_map(|(k, v)| k.strip_prefix(OPTIMISER_PREFIX).map(|k| (k.to_string(), v))).collect();
        Ok(Self { step, record, optimiser })
    }

    /// A state file from before checkpoints were one unit: moments and a `step` tensor, with
    /// the weights and record in their published files (kept readable so a run under way
    /// when this changed can still be resumed).
    fn read_legacy(path: &Path, mut tensors: HashMap<String, Tensor>, varmap: &VarMap, legacy: Legacy) -> Result<Self> {
        let name = path.display();
        let step = tensors.remove(STEP_KEY).with_context(|| format!("{name} has no step: not a training checkpoint"))?;
        let step = step.to_vec1::<f32>().ok().and_then(|v| v.first().copied()).with_context(|| format!("{name}: the step is damaged"))?;
        let record = legacy.record.with_context(|| format!("{name}: model.json has no record of this stage to resume"))?;
        if record.steps != step as usize {
            bail!("{name} is at step {step}, model.json's record at {}; they were written by different checkpoints", record.steps);
        }
        load_weights(legacy.weights, varmap).with_context(|| format!("cannot resume from {}", legacy.weights.display()))?;
        Ok(Self { step: record.steps, record, optimiser: tensors })
    }
}

/// Where a legacy state file's weights and record are.
pub(super) struct Legacy<'a> {
    pub weights: &'a Path,
    pub record: Option<StageRecord>,
}

const MAX_CHECKPOINT_BYTES: u64 = 8 << 30;
