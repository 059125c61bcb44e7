//! Messages for the user, shown as toasts over the viewport and kept in a log.
//!
//! A message about a state (the model, the generation, the initial pose, an export...)
//! carries a [`Topic`]: a newer message of the same topic replaces it, and it is withdrawn
//! when the state is fixed ([`Messages::resolve`]). Other messages fade: notices after a
//! few seconds, errors after a little longer. Everything stays in the log panel. Long texts
//! are summarised on the toast (the full text is in the log and the toast's tooltip).

use egui::{Color32, RichText};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    Info,
    Error,
}

/// The state a message is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Topic {
    Model,
    Generation,
    Init,
    Export,
    /// An export refused because the take on screen is out of date.
    Stale,
    Project,
    Classes,
    Autosave,
    Dialog,
    /// What a take could not do as its keys and path asked.
    Constraints,
    /// A timeline the model will not follow as written (see `studio::advice`).
    Advice,
}

#[derive(Clone, Debug)]
pub struct Message {
    pub level: Level,
    pub topic: Option<Topic>,
    pub text: String,
    /// egui time when it was posted.
    pub time: f64,
}

impl Message {
    /// The toast's text: the first line, at most [`Messages::SUMMARY_CHARS`] characters.
    pub fn summary(&self) -> String {
        let first = self.text.lines().next().unwrap_or("");
        let short: String = first.chars().take(Messages::SUMMARY_CHARS).collect();
        if short.len() < self.text.len() {
            format!("{short}… (full text in Help > Message log)")
        } else {
            short
        }
    }
}

#[derive(Default)]
pub struct Messages {
    list: Vec<Message>,
    log: Vec<Message>,
    now: f64,
}

impl Messages {
    const INFO_SECONDS: f64 = 5.0;
    const ERROR_SECONDS: f64 = 15.0;
    const MAX: usize = 5;
    const LOG_MAX: usize = 500;
    pub const SUMMARY_CHARS: usize = 180;

    pub fn info(&mut self, text: impl Into<String>) {
        self.push(Level::Info, None, text.into());
    }

    pub fn error(&mut self, text: impl Into<String>) {
        self.push(Level::Error, None, text.into());
    }

    /// A message about `topic`, replacing the previous one of that topic.
    pub fn set(&mut self, topic: Topic, level: Level, text: impl Into<String>) {
        self.list.retain(|m| m.topic != Some(topic));
        self.push(level, Some(topic), text.into());
    }

    /// Withdraws the message about `topic`: its state is fixed.
    pub fn resolve(&mut self, topic: Topic) {
        self.list.retain(|m| m.topic != Some(topic));
    }

    fn push(&mut self, level: Level, topic: Option<Topic>, text: String) {
        if level == Level::Error {
            eprintln!("glocal studio: {text}");
        }
        self.list.retain(|m| m.text != text);
        let message = Message { level, topic, text, time: self.now };
        self.log.push(message.clone());
        if self.log.len() > Self::LOG_MAX {
            self.log.remove(0);
        }
        self.list.push(message);
        if self.list.len() > Self::MAX {
            self.list.remove(0);
        }
    }

    /// The messages on screen.
    pub fn all(&self) -> &[Message] {
        &self.list
    }

    /// Every message of this session, oldest first.
    pub fn log(&self) -> &[Message] {
        &self.log
    }

    pub fn errors(&self) -> impl Iterator<Item = &Message> {
        self.list.iter().filter(|m| m.level == Level::Error)
    }

    pub fn clear(&mut self) {
        self.list.clear();
    }

    /// How long a message stays on screen (None: until its state changes).
    fn lifetime(m: &Message) -> Option<f64> {
        match (m.level, m.topic) {
            (Level::Error, Some(_)) => None,
            (Level::Error, None) => Some(Self::ERROR_SECONDS),
            (Level::Info, Some(Topic::Classes | Topic::Constraints)) => Some(Self::ERROR_SECONDS),
            (Level::Info, _) => Some(Self::INFO_SECONDS),
        }
    }

    /// Drops expired messages; call once a frame.
    pub fn tick(&mut self, ctx: &egui::Context) {
        self.now = ctx.input(|i| i.time);
        let now = self.now;
        self.list.retain(|m| Self::lifetime(m).is_none_or(|l| now - m.time < l));
        if let Some(next) = self.list.iter().filter_map(|m| Self::lifetime(m).map(|l| m.time + l - now)).reduce(f64::min) {
            ctx.request_repaint_after(std::time::Duration::from_secs_f64(next.max(0.05)));
        }
    }

    /// Toasts in the top right corner of `rect`, or its bottom right corner when `keep_top`
    /// (a window of its own is there, and its buttons must stay reachable).
    pub fn show(&mut self, ui: &egui::Ui, rect: egui::Rect, keep_top: bool) {
        if self.list.is_empty() {
            return;
        }
        let mut dismiss = None;
        egui::Area::new(egui::Id::unique("glocal_toasts"))
            .order(egui::Order::Foreground)
            .fixed_pos(if keep_top { rect.right_bottom() + egui::vec2(-12.0, -12.0) } else { rect.right_top() + egui::vec2(-12.0, 12.0) })
            .pivot(if keep_top { egui::Align2::RIGHT_BOTTOM } else { egui::Align2::RIGHT_TOP })
            .show(ui.ctx(), |ui| {
                ui.set_max_width(420.0);
                for (k, m) in self.list.iter().enumerate().rev() {
                    let (fill, stroke) = colours(m.level);
                    egui::Frame::new().fill(fill).stroke((1.0, stroke)).corner_radius(6.0).inner_margin(8.0).show(ui, |ui| {
                        ui.horizontal(|ui| {
                            let icon = if m.level == Level::Error { "!" } else { "i" };
                            ui.label(RichText::new(icon).color(stroke).strong());
                            let summary = m.summary();
                            let label = ui.add(egui::Label::new(RichText::new(&summary).color(Color32::WHITE)).wrap());
                            if summary != m.text {
                                label.on_hover_text(&m.text);
                            }
                            if ui.small_button("x").on_hover_text("Dismiss").clicked() {
                                dismiss = Some(k);
                            }
                        });
                    });
                    ui.add_space(4.0);
                }
            });
        if let Some(k) = dismiss {
            self.list.remove(k);
        }
    }

    /// The log, newest first, in a scroll area.
    pub fn log_ui(&self, ui: &mut egui::Ui) {
        if self.log.is_empty() {
            ui.label(RichText::new("No messages yet").weak());
        }
        egui::ScrollArea::vertical().max_height(360.0).show(ui, |ui| {
            for m in self.log.iter().rev() {
                let (_, stroke) = colours(m.level);
                ui.horizontal_wrapped(|ui| {
                    ui.label(RichText::new(format!("{:>7.1} s", m.time)).monospace().weak());
                    ui.label(RichText::new(&m.text).color(stroke));
                });
            }
        });
    }
}

fn colours(level: Level) -> (Color32, Color32) {
    match level {
        Level::Error => (Color32::from_rgb(70, 24, 24), Color32::from_rgb(220, 80, 70)),
        Level::Info => (Color32::from_rgb(28, 44, 60), Color32::from_rgb(90, 150, 210)),
    }
}

/// The first line of a message (engine errors may hold more).
pub fn first_line(text: &str) -> &str {
    text.lines().next().unwrap_or("")
}
