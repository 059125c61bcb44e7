//! A model switch in the studio: the document carried over to the newly loaded model as one
//! undoable edit (Ctrl+Z brings the old model back with the document as it was). A switch back
//! restores what the user left as the switch made it ([`ModelSwitch`]); other classes are
//! mapped by [`ClassMap`], the start moved to the mapped class, key poses retargeted onto the
//! new skeleton and keys that cannot be carried dropped by name.

use std::path::PathBuf;

use super::app::StudioApp;
use super::messages::{Level, Topic};
use super::panels::MappingNote;
use super::worker::ModelInfo;
use crate::synth::class_map::ClassMap;
use crate::synth::model_switch::{key_name, pose_onto, switch_back, ModelSwitch};
use crate::synth::{InitPose, Key, KeySource};

impl StudioApp {
    /// Switches to the model in `dir` (the user's choice): once it has loaded, the document is
    /// carried over to it as one undoable edit.
    pub fn switch_model(&mut self, dir: PathBuf) {
        self.load_model(dir);
        self.engine.switching = true;
    }

    /// Carries the document from `previous` to the model `info` just loaded, as one undo step.
    pub(super) fn carry_over(&mut self, previous: &ModelInfo, info: &ModelInfo) {
        let before = self.editing.doc.clone();
        let back = switch_back(&self.editing.switches, &previous.dir, &info.dir).map(|s| s.restore(&before.options));
        let kept_keys = match back {
            Some(back) => {
                self.editing.doc.options = back.options;
                let message = format!("Back on {}: what the switch to {} changed and was left alone is as it was", info.spec.dataset, previous.spec.dataset);
                self.messages.set(Topic::Classes, Level::Info, message);
                back.keys
            }
            None => vec![false; before.options.keys.len()],
        };
        self.editing.doc.model = info.dir.clone();
        self.carry_classes(info);
        self.carry_keys(previous, info, &kept_keys);
        self.carry_init(info);
        self.editing.switches.push(ModelSwitch::new(previous.dir.clone(), info.dir.clone(), before.options.clone(), self.editing.doc.options.clone()));
        self.editing.history.record(before);
    }

    /// The start as it settled after the last switch (a file start found not to fit is
    /// replaced once the worker has checked it): a switch back restores the file.
    pub(super) fn switch_settled(&mut self) {
        let options = self.editing.doc.options.clone();
        if let Some(last) = self.editing.switches.last_mut().filter(|s| s.to == self.editing.doc.model) {
            last.settle(options);
        }
    }

    /// Retags segments whose class the new model does not have (by [`ClassMap`]) and says
    /// what was mapped.
    pub(super) fn carry_classes(&mut self, info: &ModelInfo) {
        let cleared = self.editing.doc.options.timeline.keep_styles(&info.spec.styles);
        if cleared > 0 {
            self.messages.set(Topic::Classes, Level::Info, format!("{cleared} segments lost a style {} does not have; they take their activity's usual style", info.spec.dataset));
        }
        let classes = &info.spec.classes;
        let mut unknown: Vec<String> = Vec::new();
        for s in &self.editing.doc.options.timeline.segments {
            if info.spec.class_index(&s.class).is_err() && !unknown.contains(&s.class) {
                unknown.push(s.class.clone());
            }
        }
        if unknown.is_empty() || classes.is_empty() {
            return;
        }
        let map = ClassMap::build(&unknown, classes, &self.class_table());
        let described = map.describe(&self.editing.doc.options.timeline);
        let segments = map.pairs.iter().map(|p| self.editing.doc.options.timeline.segments.iter().enumerate().filter(|(_, s)| s.class == p.from).map(|(k, _)| k).collect()).collect();
        let (timeline, changed) = map.apply(&self.editing.doc.options.timeline);
        self.editing.doc.options.timeline = timeline;
        self.messages.set(
            Topic::Classes,
            Level::Info,
            format!("Classes carried over to {}: {described} ({changed} segments, durations kept). Edit > Class mapping… changes a pairing.", info.spec.dataset),
        );
        self.panels.mapping = Some(MappingNote { map, classes: classes.clone(), segments, timeline: self.editing.doc.options.timeline.clone() });
    }

    /// The user's pairings, then the shipped table.
    fn class_table(&self) -> Vec<(String, String)> {
        self.storage.class_table.iter().cloned().chain(ClassMap::shipped_table()).collect()
    }

    /// Keys made on `previous` (those a switch back did not restore, `kept` false) on the new
    /// model: a pose retargeted onto its skeleton, a seed pose the mapped class's typical one;
    /// a key that cannot be carried is dropped, and the message names it.
    fn carry_keys(&mut self, previous: &ModelInfo, info: &ModelInfo, kept: &[bool]) {
        let map = ClassMap::build(&previous.spec.classes, &info.spec.classes, &self.class_table());
        let mapped_class = |class: &str| info.spec.class_index(map.get(class).unwrap_or(class)).ok();
        let typical = |class: usize| InitPose::SeedClass { class: info.spec.classes[class].clone(), variant: info.typical_variant(class, 0) };
        let (mut moved, mut dropped) = (0, Vec::new());
        let keys = std::mem::take(&mut self.editing.doc.options.keys);
        for (key, &kept) in keys.into_iter().zip(kept.iter().chain(std::iter::repeat(&false))) {
            let carried = match &key.source {
                _ if kept => Ok(key.source.clone()),
                KeySource::Pose(pose) => pose_onto(pose, &previous.spec, &info.spec).map(KeySource::Pose).map_err(|e| format!("{e:#}")),
                KeySource::Init(InitPose::SeedClass { class, .. }) if info.spec.class_index(class).is_ok() => Ok(key.source.clone()),
                KeySource::Init(InitPose::SeedClass { class, .. }) => mapped_class(class).map(|c| KeySource::Init(typical(c))).ok_or_else(|| format!("no class like '{class}'")),
                KeySource::Init(InitPose::SeedIndex(i)) => {
                    let class = previous.seeds.get(*i).and_then(|s| previous.spec.classes.get(s.class));
                    class.and_then(|c| mapped_class(c)).map(|c| KeySource::Init(typical(c))).ok_or_else(|| format!("seed {i} has no counterpart"))
                }
                KeySource::Init(InitPose::File { .. }) => Ok(key.source.clone()),
            };
            match carried {
                Ok(source) => {
                    moved += usize::from(source != key.source);
                    self.editing.doc.options.keys.push(Key { source, ..key });
                }
                Err(why) => dropped.push(format!("{} ({why})", key_name(&key))),
            }
        }
        if moved > 0 || !dropped.is_empty() {
            let dropped = if dropped.is_empty() { String::new() } else { format!("; dropped {}", dropped.join(", ")) };
            let level = if dropped.is_empty() { Level::Info } else { Level::Error };
            self.messages.set(Topic::Constraints, level, format!("Keys carried over to {}: {moved} moved onto its skeleton and seed bank{dropped}", info.spec.dataset));
        }
    }

    /// Keeps the initial pose meaningful on a new model: a class start moves to the mapped
    /// class's typical window, a seed index out of range is reset, and a file is checked
    /// again (and reset with a message if it does not fit).
    pub(super) fn carry_init(&mut self, info: &ModelInfo) {
        match self.editing.doc.options.init.clone() {
            InitPose::SeedClass { class, variant } => {
                let k = match info.spec.class_index(&class) {
                    Ok(k) => k,
                    Err(_) => self.panels.mapping.as_ref().and_then(|m| m.map.get(&class)).and_then(|c| info.spec.class_index(c).ok()).unwrap_or(0),
                };
                let variant = if info.spec.classes[k] == class { variant } else { info.typical_variant(k, 0) };
                self.editing.doc.options.init = InitPose::SeedClass { class: info.spec.classes[k].clone(), variant };
            }
            InitPose::SeedIndex(i) if i >= info.seeds.len() => {
                self.editing.doc.options.init = InitPose::SeedIndex(0);
                self.messages.set(Topic::Init, Level::Info, format!("Seed {i} does not exist in the {} model: the take starts from seed 0", info.spec.dataset));
            }
            InitPose::SeedIndex(_) => {}
            init @ InitPose::File { .. } => {
                self.engine.init_after_switch = true;
                self.engine.worker.check_init(init);
            }
        }
    }

    /// Changes the counterpart of `from` in the last model switch's mapping: the segments it
    /// retagged get `to` (while the timeline is as the switch left it), and the pairing is
    /// remembered for later switches.
    pub fn set_mapping(&mut self, from: &str, to: &str) {
        let Some(note) = self.panels.mapping.as_mut() else { return };
        let Some(k) = note.map.pairs.iter().position(|p| p.from == from) else { return };
        note.map.set(from, to);
        self.storage.class_table.retain(|(a, _)| a != from);
        self.storage.class_table.insert(0, (from.to_string(), to.to_string()));
        if self.editing.doc.options.timeline.segments.len() == note.timeline.segments.len() {
            let indices = note.segments[k].clone();
            self.edit(|d| indices.iter().for_each(|&i| d.options.timeline.segments[i].class = to.to_string()));
            if let Some(note) = self.panels.mapping.as_mut() {
                note.timeline = self.editing.doc.options.timeline.clone();
            }
        }
        self.save_state();
    }
}
