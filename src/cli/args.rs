//! Command-line forms of the engine's options: the engine's own types know nothing of clap.

use crate::synth::Transition;

/// How the class changes at a segment boundary (see [`Transition`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum TransitionArg {
    Cut,
    Blend,
    Anchor,
}

impl From<TransitionArg> for Transition {
    fn from(t: TransitionArg) -> Self {
        match t {
            TransitionArg::Cut => Transition::Cut,
            TransitionArg::Blend => Transition::Blend,
            TransitionArg::Anchor => Transition::Anchor,
        }
    }
}
