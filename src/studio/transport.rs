//! Playback: the current frame, play/pause, stepping, looping and speed. Plain logic, no
//! widgets (the transport bar is drawn in `bottom.rs`).

use super::project::{LoopMode, PlaybackSettings};

#[derive(Clone, Debug, Default)]
pub struct Playback {
    pub playing: bool,
    /// Fractional frame position.
    position: f64,
    /// In/out frames `[start, end)` of the selected range.
    pub selection: Option<(usize, usize)>,
}

impl Playback {
    pub fn frame(&self) -> usize {
        self.position.max(0.0) as usize
    }

    pub fn seek(&mut self, frame: usize, frames: usize) {
        self.position = frame.min(frames.saturating_sub(1)) as f64;
    }

    /// Moves by whole frames (stepping pauses playback).
    pub fn step(&mut self, delta: i64, frames: usize) {
        self.playing = false;
        let f = (self.frame() as i64 + delta).clamp(0, frames.saturating_sub(1) as i64);
        self.position = f as f64;
    }

    pub fn toggle(&mut self, frames: usize, settings: &PlaybackSettings) {
        self.playing = !self.playing && frames > 1;
        // Playing from the end starts again.
        if self.playing && self.frame() + 1 >= frames && settings.loop_mode == LoopMode::Off {
            self.position = 0.0;
        }
    }

    /// The frames playback runs over for a loop mode.
    pub fn range(&self, frames: usize, mode: LoopMode) -> (usize, usize) {
        match (mode, self.selection) {
            (LoopMode::Selection, Some((a, b))) if b > a && a < frames => (a, b.min(frames)),
            _ => (0, frames),
        }
    }

    /// Advances by `dt` seconds of wall time over a take of `frames` frames; a `growing` take
    /// (still being made) is waited for at its last frame instead of looped or stopped.
    pub fn advance(&mut self, dt: f64, fps: f32, frames: usize, settings: &PlaybackSettings, growing: bool) {
        if growing && self.playing {
            self.position = (self.position + dt * f64::from(fps) * f64::from(settings.speed)).min(frames.saturating_sub(1) as f64);
            return;
        }
        if !self.playing || frames < 2 {
            self.playing = false;
            return;
        }
        let (lo, hi) = self.range(frames, settings.loop_mode);
        if self.position < lo as f64 || self.position >= hi as f64 {
            self.position = lo as f64;
        }
        self.position += dt * f64::from(fps) * f64::from(settings.speed);
        if self.position >= hi as f64 {
            match settings.loop_mode {
                LoopMode::Off => {
                    self.position = (hi - 1) as f64;
                    self.playing = false;
                }
                LoopMode::All | LoopMode::Selection => {
                    let span = (hi - lo) as f64;
                    self.position = lo as f64 + (self.position - lo as f64) % span;
                }
            }
        }
    }

    /// Keeps the position and selection inside a take of `frames` frames.
    pub fn clamp(&mut self, frames: usize) {
        if self.frame() >= frames {
            self.position = frames.saturating_sub(1) as f64;
        }
        if let Some((a, b)) = self.selection {
            let (a, b) = (a.min(frames), b.min(frames));
            self.selection = (b > a).then_some((a, b));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loops_and_stops() {
        let mut p = Playback::default();
        let mut s = PlaybackSettings { speed: 1.0, loop_mode: LoopMode::Off };
        p.toggle(100, &s);
        p.advance(2.0, 25.0, 100, &s, false);
        assert_eq!(p.frame(), 50);
        p.advance(10.0, 25.0, 100, &s, false);
        assert_eq!((p.frame(), p.playing), (99, false));
        s.loop_mode = LoopMode::Selection;
        p.selection = Some((10, 20));
        p.toggle(100, &s);
        p.advance(0.2, 25.0, 100, &s, false);
        assert_eq!(p.frame(), 15);
        p.advance(0.4, 25.0, 100, &s, false);
        assert_eq!(p.frame(), 15);
        p.step(-20, 100);
        assert_eq!((p.frame(), p.playing), (0, false));
    }
}
