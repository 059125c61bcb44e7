//! AdamW over candle `Var`s with its moments in plain f32 buffers, so that a checkpoint can
//! hold the optimiser state and a resumed run continues exactly where it stopped.

use std::collections::HashMap;

use candle_core::{backprop::GradStore, Result, Tensor, Var};

pub struct AdamW {
    vars: Vec<(String, Var)>,
    pub m: HashMap<String, Vec<f32>>,
    pub v: HashMap<String, Vec<f32>>,
    pub step: usize,
    pub lr: f32,
    beta1: f32,
    beta2: f32,
    eps: f32,
    weight_decay: f32,
}

impl AdamW {
    /// `vars` by name; sorted so that the order never depends on a hash map.
    pub fn new(mut vars: Vec<(String, Var)>, lr: f32) -> Self {
        vars.sort_by(|a, b| a.0.cmp(&b.0));
        Self { vars, m: HashMap::new(), v: HashMap::new(), step: 0, lr, beta1: 0.9, beta2: 0.999, eps: 1e-8, weight_decay: 0.01 }
    }

    pub fn backward_step(&mut self, loss: &Tensor) -> Result<()> {
        let grads = loss.backward()?;
        self.apply(&grads)
    }

    fn apply(&mut self, grads: &GradStore) -> Result<()> {
        self.step += 1;
        let t = self.step as i32;
        let (b1, b2) = (self.beta1, self.beta2);
        let bc1 = 1.0 - b1.powi(t);
        let bc2 = 1.0 - b2.powi(t);
        for (name, var) in &self.vars {
            let Some(g) = grads.get(var.as_tensor()) else { continue };
            let g = g.flatten_all()?.to_vec1::<f32>()?;
            let mut w = var.as_tensor().flatten_all()?.to_vec1::<f32>()?;
            let m = self.m.entry(name.clone()).or_insert_with(|| vec![0.0; w.len()]);
            let v = self.v.entry(name.clone()).or_insert_with(|| vec![0.0; w.len()]);
            let decay = 1.0 - self.lr * self.weight_decay;
            for k in 0..w.len() {
                m[k] = b1 * m[k] + (1.0 - b1) * g[k];
                v[k] = b2 * v[k] + (1.0 - b2) * g[k] * g[k];
                let update = (m[k] / bc1) / ((v[k] / bc2).sqrt() + self.eps);
                w[k] = w[k] * decay - self.lr * update;
            }
            var.set(&Tensor::from_vec(w, var.shape(), var.device())?)?;
        }
        Ok(())
    }

    /// The moments as named tensors, for a checkpoint.
    pub fn state_tensors(&self) -> Result<Vec<(String, Tensor)>> {
        let mut out = Vec::new();
        for (name, var) in &self.vars {
            if let (Some(m), Some(v)) = (self.m.get(name), self.v.get(name)) {
                out.push((format!("m.{name}"), Tensor::from_slice(m, var.shape(), var.device())?));
                out.push((format!("v.{name}"), Tensor::from_slice(v, var.shape(), var.device())?));
            }
        }
        Ok(out)
    }

    /// Restores moments saved by [`Self::state_tensors`].
    pub fn load_state(&mut self, tensors: &HashMap<String, Tensor>, step: usize) -> Result<()> {
        self.step = step;
        for (name, _) in &self.vars {
            if let (Some(m), Some(v)) = (tensors.get(&format!("m.{name}")), tensors.get(&format!("v.{name}"))) {
                self.m.insert(name.clone(), m.flatten_all()?.to_vec1()?);
                self.v.insert(name.clone(), v.flatten_all()?.to_vec1()?);
            }
        }
        Ok(())
    }
}
