//! The training loss of both stages (paper eq. 3): λ1·L_J + λ2·L_MF with λ1 = λ2 = 1, mean
//! squared errors of the poses and of their frame-to-frame motion flow.

use candle_core::{Result, Tensor};

use super::spec::LossKind;

/// The loss of predicted poses `pred [B, T, D]` against `target`. With `last_input` (the pose
/// before the block, `[B, 1, D]`) the motion flow includes the step into the block, so blocks
/// join smoothly; without it the flow is the block's own steps.
pub fn joint_flow_loss(pred: &Tensor, target: &Tensor, last_input: Option<&Tensor>, kind: LossKind) -> Result<Tensor> {
    let joint = (pred - target)?.sqr()?.mean_all()?;
    let flow = || -> Result<Option<Tensor>> {
        let (p, t) = match last_input {
            Some(last) => (Tensor::cat(&[last, pred], 1)?, Tensor::cat(&[last, target], 1)?),
            None => (pred.clone(), target.clone()),
        };
        let steps = p.dim(1)? - 1;
        if steps == 0 {
            return Ok(None);
        }
        let vp = (p.narrow(1, 1, steps)? - p.narrow(1, 0, steps)?)?;
        let vt = (t.narrow(1, 1, steps)? - t.narrow(1, 0, steps)?)?;
        Ok(Some((vp - vt)?.sqr()?.mean_all()?))
    };
    if kind == LossKind::Joint {
        return Ok(joint);
    }
    Ok(match (kind, flow()?) {
        (LossKind::JointFlow, Some(flow)) => (joint + flow)?,
        (_, Some(flow)) => flow,
        // A single pose with nothing before it has no flow.
        (LossKind::Flow, None) => joint.zeros_like()?,
        (_, None) => joint,
    })
}

/// The block-level loss of the benchmark and the block's tests: joint and flow over the
/// block's own steps.
pub fn motion_loss(out: &Tensor, y: &Tensor) -> Result<Tensor> {
    joint_flow_loss(out, y, None, LossKind::JointFlow)
}
