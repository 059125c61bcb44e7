//! The left panel: project, model, initial pose, generation settings and export.

use std::path::PathBuf;

use egui::{RichText, Slider};

use super::advice::seated_too_short;
use super::app::StudioApp;
use super::panels::{ExportRange, Guarded, InitTab, MAX_INIT_FRAME};
use super::dialogs::Purpose;
use super::timeline::color32;
use super::worker::ModelInfo;
use crate::model::spec::DEFAULT_CLASS_STRENGTH;
use crate::motion::RootMotion;
use crate::synth::export::Units;
use crate::synth::render::class_color;
use crate::synth::timeline::{MAX_PACE, MAX_TRANSITION_SECONDS, MIN_PACE};
use crate::synth::{InitPose, Preset, Transition};

fn section(ui: &mut egui::Ui, title: &str, add: impl FnOnce(&mut egui::Ui)) {
    egui::CollapsingHeader::new(RichText::new(title).strong()).default_open(true).show(ui, add);
    ui.add_space(2.0);
}

/// A text field with a label the tests (and screen readers) can find.
fn path_field(ui: &mut egui::Ui, label: &str, value: &mut String, hint: &str) -> egui::Response {
    let l = ui.label(label);
    ui.add(egui::TextEdit::singleline(value).hint_text(hint).desired_width(f32::INFINITY)).labelled_by(l.id)
}

impl StudioApp {
    pub(super) fn side_panel(&mut self, ui: &mut egui::Ui) {
        ui.add_space(4.0);
        // The project first: it is what a session starts and ends with.
        section(ui, "Project", |ui| self.project_section(ui));
        section(ui, "Model", |ui| self.model_section(ui));
        section(ui, "Initial pose", |ui| self.init_section(ui));
        self.advice_ui(ui);
        section(ui, "Generation", |ui| self.generation_section(ui));
        section(ui, "Keys and path", |ui| self.keys_section(ui));
        section(ui, "Export take", |ui| self.export_section(ui));
    }

    /// Timelines the model will not follow as written (see [`super::advice`]), with fixes.
    fn advice_ui(&mut self, ui: &mut egui::Ui) {
        let found = seated_too_short(&self.editing.doc.options.timeline, self.classes());
        for short in found {
            ui.label(RichText::new(format!("{} (now {:.1} s)", short.message(), short.seconds)).color(ui.visuals().warn_fg_color));
            ui.horizontal_wrapped(|ui| {
                for fix in &short.fixes {
                    if ui.button(fix.label()).clicked() {
                        self.edit(|d| fix.apply(&mut d.options.timeline));
                    }
                }
            });
            ui.add_space(4.0);
        }
    }

    fn model_section(&mut self, ui: &mut egui::Ui) {
        match &self.engine.model {
            Some(m) => {
                let s = &m.spec;
                ui.label(RichText::new(m.dir.display().to_string()).monospace());
                ui.label(format!("{} · {} classes · {} fps · {} joints", s.dataset, s.classes.len(), s.fps, s.layout.joints()));
                if !m.has_locgen {
                    ui.label(RichText::new("No LocGen yet: frames are interpolated").weak());
                }
            }
            None => {
                ui.label(RichText::new("No model loaded").weak());
            }
        }
        if let Some(dir) = &self.engine.model_loading {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label(format!("Loading {}…", dir.display()));
            });
        }
        let looked = self.storage.model_roots.iter().map(|r| r.display().to_string()).collect::<Vec<_>>().join("\n");
        if !self.storage.shipped.is_empty() {
            ui.horizontal_wrapped(|ui| {
                ui.label("Shipped:").on_hover_text(format!("Models are looked for in\n{looked}"));
                for dir in self.storage.shipped.clone() {
                    let name = dir.file_name().map_or_else(|| dir.display().to_string(), |n| n.to_string_lossy().into_owned());
                    let current = self.engine.model.as_ref().is_some_and(|m| m.dir == dir);
                    if ui.selectable_label(current, name).clicked() && !current {
                        self.switch_model(dir);
                    }
                }
            });
        }
        let r = path_field(ui, "Model folder", &mut self.panels.fields.model_path, "path/to/model");
        let enter = r.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
        ui.horizontal(|ui| {
            if ui.button("Load model").clicked() || enter {
                let p = PathBuf::from(self.panels.fields.model_path.trim());
                self.switch_model(p);
            }
            if ui.button("Browse…").clicked() {
                self.open_dialog(Purpose::OpenModel, ui.ctx());
            }
        });
    }

    fn init_section(&mut self, ui: &mut egui::Ui) {
        let Some(model) = self.engine.model.clone() else {
            ui.label(RichText::new("Load a model first").weak());
            return;
        };
        ui.horizontal(|ui| {
            for (tab, name, tip) in [
                (InitTab::Class, "By class", "A typical pose of a class"),
                (InitTab::Seed, "Seed", "Any pose of the seed bank (or click the seed map)"),
                (InitTab::File, "File", "A pose from a BVH, NPY or dataset file"),
            ] {
                if ui.selectable_label(self.panels.init_tab == tab, name).on_hover_text(tip).clicked() && self.panels.init_tab != tab {
                    self.set_init_tab(tab);
                }
            }
        });
        match self.panels.init_tab {
            InitTab::Class => self.init_class_tab(ui, &model),
            InitTab::Seed => self.init_seed_tab(ui, &model),
            InitTab::File => self.init_file_tab(ui),
        }
    }

    /// A typical pose of a class, by class and rank.
    fn init_class_tab(&mut self, ui: &mut egui::Ui, model: &ModelInfo) {
        let classes = &model.spec.classes;
        let (class, rank) = match &self.editing.doc.options.init {
            InitPose::SeedClass { class, variant } => {
                let k = model.spec.class_index(class).unwrap_or(0);
                (k, model.typical_rank(k, *variant))
            }
            _ => (0, 0),
        };
        let (mut new_class, mut new_rank) = (class, rank);
        egui::ComboBox::from_label("Start class").selected_text(&classes[class]).height(400.0).show_ui(ui, |ui| {
            for (k, c) in classes.iter().enumerate() {
                ui.selectable_value(&mut new_class, k, c);
            }
        });
        if new_class != class {
            new_rank = 0;
        }
        let n = model.seeds.iter().filter(|s| s.class == new_class).count().max(1);
        ui.add(Slider::new(&mut new_rank, 0..=n - 1).text("variant"))
            .on_hover_text("0 is the class's most typical pose; higher numbers are less typical examples");
        // The window the start is, whose clip names its style on Bandai's data.
        let variant = model.typical_variant(new_class, new_rank);
        if let Some(s) = model.seeds.iter().filter(|s| s.class == new_class).nth(variant) {
            ui.label(RichText::new(format!("{} @ {}", s.clip, s.frame)).weak());
        }
        if (new_class, new_rank) != (class, rank) || !matches!(self.editing.doc.options.init, InitPose::SeedClass { .. }) {
            self.set_init_class(new_class, new_rank);
        }
    }

    /// Any seed of the bank, by index.
    fn init_seed_tab(&mut self, ui: &mut egui::Ui, model: &ModelInfo) {
        let classes = &model.spec.classes;
        let mut index = match &self.editing.doc.options.init {
            InitPose::SeedIndex(i) => *i,
            _ => self.panels.fields.seed_index,
        };
        if let Some(s) = model.seeds.get(index) {
            ui.horizontal(|ui| {
                let (r, _) = ui.allocate_exact_size(egui::vec2(10.0, 10.0), egui::Sense::hover());
                ui.painter().circle_filled(r.center(), 5.0, color32(class_color(s.class)));
                ui.label(format!("{} · {} @ {}", classes[s.class], s.clip, s.frame));
            });
        }
        let max = model.seeds.len().saturating_sub(1);
        if ui.add(Slider::new(&mut index, 0..=max).text("seed")).changed() || !matches!(self.editing.doc.options.init, InitPose::SeedIndex(_)) {
            self.panels.fields.seed_index = index;
            self.editing.doc.options.init = InitPose::SeedIndex(index);
        }
        ui.label(RichText::new("Or click a point in the seed map").weak());
    }

    /// A motion file and the frame it starts from.
    fn init_file_tab(&mut self, ui: &mut egui::Ui) {
        match &self.editing.doc.options.init {
            InitPose::File { path, frame, .. } => ui.label(format!("In use: {} @ {frame}", path.display())),
            _ => ui.label(RichText::new("No file in use yet: the take starts from the previous choice").weak()),
        };
        path_field(ui, "Motion file (BVH, NPY or dataset .txt)", &mut self.panels.fields.init_path, "clip.bvh");
        ui.add(egui::DragValue::new(&mut self.panels.fields.init_frame).range(0..=MAX_INIT_FRAME).prefix("from frame "));
        ui.horizontal(|ui| {
            if ui.button("Use file").clicked() {
                let p = PathBuf::from(self.panels.fields.init_path.trim());
                self.retarget_file(super::retarget::PreviewFor::Init, p, self.panels.fields.init_frame);
            }
            if ui.button("Browse…").clicked() {
                self.open_dialog(Purpose::InitFile, ui.ctx());
            }
        });
    }

    fn generation_section(&mut self, ui: &mut egui::Ui) {
        let has_locgen = self.engine.model.as_ref().is_some_and(|m| m.has_locgen);
        let guidance = self.engine.model.as_ref().is_some_and(|m| m.spec.glogen.class_dropout > 0.0);
        ui.add(Slider::new(&mut self.editing.doc.options.pace, MIN_PACE..=4.0f32.min(MAX_PACE)).logarithmic(true).text("global pace"))
            .on_hover_text("How long each pose lasts: 2 plays the motion twice as slowly (over twice the time), 0.5 twice as fast. A segment with its own pace uses that instead.");
        ui.horizontal(|ui| {
            ui.label("Transitions:");
            ui.selectable_value(&mut self.editing.doc.options.transition, Transition::Anchor, "Anchor")
                .on_hover_text("The new activity takes over within about two seconds, even from a very different motion (recommended)");
            ui.selectable_value(&mut self.editing.doc.options.transition, Transition::Blend, "Blend")
                .on_hover_text("The two activities mix over about two seconds around the change; a strong motion may carry on for a while");
            ui.selectable_value(&mut self.editing.doc.options.transition, Transition::Cut, "Cut")
                .on_hover_text("The activity switches at the boundary; the previous motion's momentum can carry on (the paper's method)");
        });
        if ui.button("The paper's method").on_hover_text("GlocalNet as the paper generates: cut transitions, class strength 1, no keep-alive, no seam join, no foot lock (glocal generate --paper); Ctrl+Z undoes it").clicked() {
            self.edit(|p| p.options = Preset::Paper.apply(p.options.clone()));
        }
        ui.add(Slider::new(&mut self.editing.doc.options.transition_seconds, 0.0..=MAX_TRANSITION_SECONDS).text("transition length (s)"))
            .on_hover_text("Seconds over which each class change happens, centred on its boundary (0: a cut). A segment can have its own: select it on the timeline");
        // Until it is moved, the slider shows (and takes are made with) the model's own strength.
        let own = self.engine.model.as_ref().map_or(DEFAULT_CLASS_STRENGTH, |m| m.spec.class_strength);
        // A calibrated model's classes with their own strength, which the slider overrides.
        let per_class = self.engine.model.as_ref().map_or(String::new(), |m| {
            let own: Vec<String> = m.spec.class_strengths.iter().map(|(class, w)| format!("{class} {w}")).collect();
            let apart: Vec<String> = m.spec.class_contrasts.iter().map(|(class, pair)| format!("{class} from {pair}")).collect();
            let own = if own.is_empty() { String::new() } else { format!(" ({} have their own until the slider is moved)", own.join(", ")) };
            let apart = if apart.is_empty() { String::new() } else { format!("; steered away from the activity each is mistaken for: {}", apart.join(", ")) };
            own + &apart
        });
        let mut strength = self.editing.doc.options.class_strength.unwrap_or(own);
        let slider = ui
            .add_enabled(guidance, Slider::new(&mut strength, 0.0..=4.0).text("class strength"))
            .on_hover_text(format!("How clearly each segment shows its activity: 1 is the model as trained, higher is more typical of the activity but less varied, 0 ignores the activity. This model's own: {own}{per_class}"))
            .on_disabled_hover_text("This model was trained without class dropout, so the strength cannot be changed");
        if slider.changed() {
            self.editing.doc.options.class_strength = Some(strength);
        }
        let locks_feet = self.engine.model.as_ref().is_some_and(|m| m.spec.foot_lock);
        ui.horizontal_wrapped(|ui| {
            let options = &self.editing.doc.options;
            let mut refines = self.engine.model.as_ref().map_or(options.locgen == Some(true), |m| options.locgen_for(&m.spec));
            let toggled = ui
                .add_enabled(has_locgen, egui::Checkbox::new(&mut refines, "LocGen refinement"))
                .on_hover_text("Adds in-between motion (weight shifts, swing) to the spline between the model's key poses. Off by default where it takes the motion further from capture (Bandai's)");
            if toggled.changed() {
                self.editing.doc.options.locgen = Some(refines);
            }
            ui.add_enabled(locks_feet, egui::Checkbox::new(&mut self.editing.doc.options.foot_lock, "Foot lock"))
                .on_hover_text("Keeps planted feet still on the floor (leg IK), marked orange on the feet and on the timeline's feet track. Off: the feet as the network made them, for comparison")
                .on_disabled_hover_text("This model's takes are left as the network made them (its model.json turns the foot lock off)");
            let holds_course = self.engine.model.as_ref().is_some_and(|m| m.spec.hold_course);
            ui.add_enabled(holds_course, egui::Checkbox::new(&mut self.editing.doc.options.hold_course, "Hold course"))
                .on_hover_text("Walks, runs and sidesteps keep a straight course where no root path is drawn. Off: they turn as the network makes them (this model's walk goes round in circles)")
                .on_disabled_hover_text("This model's walks keep the course the network gives them (its model.json does not hold it)");
            let has_texture = self.engine.model.as_ref().is_some_and(|m| m.has_texture);
            ui.add_enabled(has_texture, egui::Checkbox::new(&mut self.editing.doc.options.texture, "Motion texture"))
                .on_hover_text("Lays the fine detail of each activity's capture (the small shakes and snaps a spline between key poses smooths away) over the frames between them. Off: the smooth in-betweens, for comparison")
                .on_disabled_hover_text("This model ships no motion texture");
            let has_turn_limits = self.engine.model.as_ref().is_some_and(|m| !m.spec.bone_turn_limits.is_empty());
            ui.add_enabled(has_turn_limits, egui::Checkbox::new(&mut self.editing.doc.options.spread_snaps, "Spread snaps"))
                .on_hover_text("A bone that turns farther in one frame than the activity's capture ever does (a hand flicking round) has the turn spread over the frames around it. Off: every bone as the network made it, for comparison")
                .on_disabled_hover_text("This model's model.json has no turn limits (glocal calibrate --clips-only writes them)");
        });
        ui.horizontal(|ui| {
            let mut seed = self.editing.doc.options.seed;
            let r = ui.add(egui::DragValue::new(&mut seed).range(0..=9999))
                .on_hover_text("Another version of the same timeline: 0 is the model's standard take, every other number a slightly different one");
            if r.changed() {
                self.editing.doc.set_variation_seed(seed);
            }
            ui.label("variation seed");
        });
        ui.checkbox(&mut self.engine.auto_regen, "Regenerate after every edit");
        ui.horizontal(|ui| {
            if ui.add_enabled(self.engine.model.is_some(), egui::Button::new("Generate")).clicked() {
                self.regenerate();
            }
            if let Some((_, p)) = self.engine.pending {
                if ui.button("Cancel").clicked() {
                    self.cancel();
                }
                ui.add(egui::ProgressBar::new(p).show_percentage().desired_width(110.0));
            }
        });
        if let Some(t) = &self.engine.take {
            ui.label(RichText::new(format!("{} frames ({:.1} s) in {:.0} ms", t.motion.frames(), t.motion.seconds(), t.millis)).weak());
        }
    }

    fn export_section(&mut self, ui: &mut egui::Ui) {
        path_field(ui, "Export file (.bvh, .json, .npy or .glb)", &mut self.panels.fields.export_path, "take.bvh");
        ui.horizontal(|ui| {
            for (ext, name) in [("bvh", "BVH"), ("json", "JSON"), ("npy", "NPY"), ("glb", "GLB")] {
                let current = PathBuf::from(&self.panels.fields.export_path);
                let is = current.extension().is_some_and(|e| e.eq_ignore_ascii_case(ext));
                if ui.selectable_label(is, name).clicked() {
                    self.panels.fields.export_path = current.with_extension(ext).display().to_string();
                }
            }
        });
        path_field(ui, "On a rig (optional): a BVH whose skeleton the take is written on", &mut self.panels.fields.export_rig, "my_rig.bvh");
        self.export_format(ui);
        self.export_buttons(ui);
    }

    /// Units, frame rate, the source root joint and the root motion of the export.
    fn export_format(&mut self, ui: &mut egui::Ui) {
        let (native_unit, native_fps, root) = match &self.engine.model {
            Some(m) => {
                let unit = match m.spec.layout.skeleton.meters_per_unit() {
                    u if (u - 0.001).abs() < 1e-6 => "mm".to_string(),
                    u if (u - 0.01).abs() < 1e-6 => "cm".to_string(),
                    u => format!("{u} m"),
                };
                let src = &m.spec.source_skeleton;
                let root = src.names().first().cloned().filter(|r| !m.spec.layout.skeleton.names().contains(r));
                (unit, m.spec.fps, root)
            }
            None => ("native".to_string(), 25.0, None),
        };
        let o = &mut self.panels.export_options;
        // Units and frame rates side by side: a popup below the sidebar's last rows was
        // clipped at 1280x800 and 60 fps could not be chosen.
        ui.horizontal(|ui| {
            ui.label("Units");
            ui.selectable_value(&mut o.units, Units::Metres, "metres").on_hover_text("What game engines and Blender expect");
            ui.selectable_value(&mut o.units, Units::Centimetres, "centimetres");
            ui.selectable_value(&mut o.units, Units::Native, format!("model's ({native_unit})"));
        });
        ui.horizontal(|ui| {
            ui.label("fps");
            ui.selectable_value(&mut o.fps, None, format!("{native_fps} (model)"));
            for f in [24.0, 30.0, 60.0] {
                ui.selectable_value(&mut o.fps, Some(f), format!("{f}"));
            }
        });
        let tip = match &root {
            Some(r) => format!("Adds the source skeleton's root '{r}' above the hips, on the ground under them, as in the original data"),
            None => "This model's skeleton already has the source's root joint".to_string(),
        };
        let travel = o.root_motion == RootMotion::Travel;
        ui.add_enabled(root.is_some() && travel, egui::Checkbox::new(&mut o.source_root, "Keep the source root joint")).on_hover_text(&tip).on_disabled_hover_text(&tip);
        ui.horizontal(|ui| {
            ui.label("Root motion");
            let modes = [
                (RootMotion::Travel, "travel", "The hips travel and turn, as generated"),
                (RootMotion::InPlace, "in place", "The hips' travel and turning taken out: the body moves on the spot (a game's locomotion cycle)"),
                (RootMotion::RootBone, "root bone", "An added 'root' joint on the floor under the hips carries the travel and turning, as Unreal's and Unity's root-motion import expects"),
            ];
            for (mode, label, tip) in modes {
                ui.selectable_value(&mut o.root_motion, mode, label).on_hover_text(tip);
            }
        });
        self.loop_toggle(ui);
    }

    /// Loop: the take (one activity) cut to a cycle whose end joins its start, and what one
    /// play of it does.
    fn loop_toggle(&mut self, ui: &mut egui::Ui) {
        let mut looping = self.editing.doc.options.cycle;
        let one_activity = self.editing.doc.options.timeline.segments.len() == 1;
        let tip = "Cut the take to a cycle of about its length whose end joins its start in pose and velocity, for a game engine's loop (with 'in place' for a locomotion cycle on the spot)";
        let why = "A loop is one activity: keep one segment on the timeline";
        let toggle = ui.add_enabled(one_activity || looping, egui::Checkbox::new(&mut looping, "Loop")).on_hover_text(tip).on_disabled_hover_text(why);
        if toggle.changed() {
            self.edit(|p| p.options.cycle = looping);
        }
        let cycle = self.engine.take.as_ref().and_then(|t| t.cycle.as_ref().map(|c| c.summary(t.motion.fps, t.motion.skeleton.meters_per_unit())));
        if let Some(summary) = cycle {
            ui.label(RichText::new(summary).weak().small());
        }
    }

    /// Whole take or range, and the export buttons (off while the take is out of date).
    fn export_buttons(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            ui.radio_value(&mut self.panels.export_range, ExportRange::Whole, "Whole take");
            let label = self.range_label().map_or_else(|| "Selected range".to_string(), |l| l.replacen("Range", "Selected range", 1));
            ui.add_enabled(self.playback.selection.is_some(), egui::RadioButton::new(self.panels.export_range == ExportRange::Selection, label))
                .clicked()
                .then(|| self.panels.export_range = ExportRange::Selection);
        });
        let stale = self.stale_reason();
        if let Some(why) = &stale {
            ui.label(RichText::new(format!("Out of date: {why}")).color(ui.visuals().warn_fg_color));
        }
        let ready = self.engine.take.is_some() && stale.is_none();
        ui.horizontal(|ui| {
            let why = stale.clone().unwrap_or_else(|| "Nothing generated yet".into());
            if ui.add_enabled(ready, egui::Button::new("Export")).on_disabled_hover_text(&why).clicked() {
                let p = PathBuf::from(self.panels.fields.export_path.trim());
                self.export_to(p);
            }
            if ui.add_enabled(ready, egui::Button::new("Export…")).on_disabled_hover_text(&why).clicked() {
                self.open_dialog(Purpose::Export, ui.ctx());
            }
        });
    }

    fn project_section(&mut self, ui: &mut egui::Ui) {
        path_field(ui, "Project file", &mut self.panels.fields.project_path, "project.glocal.json");
        ui.horizontal_wrapped(|ui| {
            if ui.button("Open").clicked() {
                let p = PathBuf::from(self.panels.fields.project_path.trim());
                self.request(Guarded::Open(p));
            }
            if ui.button("Save").clicked() {
                let p = PathBuf::from(self.panels.fields.project_path.trim());
                self.save_project(&p);
            }
            if ui.button("Open…").clicked() {
                self.open_dialog(Purpose::OpenProject, ui.ctx());
            }
            if ui.button("Save as…").clicked() {
                self.open_dialog(Purpose::SaveProject, ui.ctx());
            }
        });
        let status = if self.has_unsaved_work() { "unsaved changes" } else { "saved" };
        let label = ui.label(RichText::new(format!("{status} · autosaved")).weak().small());
        if let Some(p) = &self.storage.autosave {
            label.on_hover_text(format!("Autosave: {}", p.display()));
        }
    }
}
