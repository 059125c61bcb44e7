//! Named sets of generation options. The paper's GlocalNet is one definition here, used by
//! `glocal generate --paper`, `glocal eval --paper` and the studio alike, so the three
//! cannot disagree about what the paper's method is.

use super::options::{GenerateOptions, Transition};

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Preset {
    /// The product's method: every addition on (anchored transitions, guidance, keep-alive,
    /// seam joins, foot lock, texture, snaps spread), each as the options say.
    #[default]
    Shipped,
    /// The paper's GlocalNet: cut transitions, plain conditioning, no keep-alive, blocks that
    /// pop at their seams, feet as the network made them, LocGen refining the frames between
    /// its poses.
    Paper,
}

impl Preset {
    /// `opts` under this preset: the paper's turns every addition off; the shipped one
    /// leaves the options as they are.
    pub fn apply(self, mut opts: GenerateOptions) -> GenerateOptions {
        if self == Preset::Paper {
            opts.transition = Transition::Cut;
            opts.transition_seconds = 0.0;
            opts.class_strength = Some(1.0);
            opts.locgen = Some(true);
            opts.keep_alive = false;
            opts.join_seams = false;
            opts.foot_lock = false;
            opts.hold_course = false;
            opts.texture = false;
            opts.spread_snaps = false;
        }
        opts
    }

    /// The preset a `--paper` flag asks for.
    pub fn from_paper_flag(paper: bool) -> Self {
        if paper {
            Preset::Paper
        } else {
            Preset::Shipped
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_paper_turns_every_addition_off_and_the_shipped_preset_nothing() {
        let shipped = GenerateOptions::default();
        assert_eq!(Preset::Shipped.apply(shipped.clone()), shipped);
        let paper = Preset::Paper.apply(shipped);
        assert_eq!((paper.transition, paper.transition_seconds, paper.class_strength, paper.locgen), (Transition::Cut, 0.0, Some(1.0), Some(true)));
        assert!(!(paper.keep_alive || paper.join_seams || paper.foot_lock || paper.hold_course || paper.texture || paper.spread_snaps));
    }
}
