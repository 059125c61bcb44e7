//! The candle-nn reference: the same layer through candle-nn's `LSTM`, built on demand from a
//! [`BiLstm`]'s own weight tensors (so gradients reach the same variables). Nothing on the
//! training or generation path uses it; the equivalence tests check the fused op and the
//! frozen path against it, and `glocal bench` times it as the baseline.
use super::{BiLstm, LstmWeights};
use candle_core::{Result, Tensor};
use candle_nn::rnn::{Direction, LSTMConfig, LSTM, RNN};
use candle_nn::VarBuilder;
use std::collections::HashMap;

/// candle-nn's LSTM over one direction's weights (candle-nn's names, which ours are).
fn candle_nn_lstm(lstm: &BiLstm, w: &LstmWeights, direction: Direction) -> Result<LSTM> {
    let sfx = match direction {
        Direction::Forward => "",
        Direction::Backward => "_reverse",
    };
    let tensors = HashMap::from([
        (format!("weight_ih_l0{sfx}"), w.w_ih.clone()),
        (format!("weight_hh_l0{sfx}"), w.w_hh.clone()),
        (format!("bias_ih_l0{sfx}"), w.b_ih.clone()),
        (format!("bias_hh_l0{sfx}"), w.b_hh.clone()),
    ]);
    let vb = VarBuilder::from_tensors(tensors, w.w_ih.dtype(), w.w_ih.device());
    LSTM::new(lstm.in_dim, lstm.hidden, LSTMConfig { direction, ..LSTMConfig::default() }, vb)
}

impl BiLstm {
    /// The same computation as [`BiLstm::forward`] through candle-nn's `LSTM` (the backward
    /// one over the reversed sequence), for tests and benchmarks.
    pub fn forward_reference(&self, x: &Tensor) -> Result<Tensor> {
        let fwd = candle_nn_lstm(self, &self.fwd, Direction::Forward)?;
        let bwd = candle_nn_lstm(self, &self.bwd, Direction::Backward)?;
        let t = x.dim(1)?;
        let rev: Vec<u32> = (0..t as u32).rev().collect();
        let rev = Tensor::new(rev.as_slice(), x.device())?;
        let f = fwd.states_to_tensor(&fwd.seq(x)?)?;
        let xr = x.index_select(&rev, 1)?;
        let br = bwd.states_to_tensor(&bwd.seq(&xr)?)?;
        let bk = br.index_select(&rev, 1)?;
        Tensor::cat(&[&f, &bk], 2)
    }
}
