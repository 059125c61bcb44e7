//! Messages for the user: errors stay until dismissed, notices fade after a few seconds.
//! Shown as toasts over the viewport.

use egui::{Color32, RichText};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    Info,
    Error,
}

#[derive(Clone, Debug)]
pub struct Message {
    pub level: Level,
    pub text: String,
    /// egui time when it was posted.
    pub time: f64,
}

#[derive(Default)]
pub struct Messages {
    list: Vec<Message>,
    now: f64,
}

impl Messages {
    const INFO_SECONDS: f64 = 5.0;
    const MAX: usize = 6;

    pub fn info(&mut self, text: impl Into<String>) {
        self.push(Level::Info, text.into());
    }

    pub fn error(&mut self, text: impl Into<String>) {
        let text = text.into();
        log_error(&text);
        self.push(Level::Error, text);
    }

    fn push(&mut self, level: Level, text: String) {
        self.list.retain(|m| m.text != text);
        self.list.push(Message { level, text, time: self.now });
        if self.list.len() > Self::MAX {
            self.list.remove(0);
        }
    }

    pub fn all(&self) -> &[Message] {
        &self.list
    }

    pub fn errors(&self) -> impl Iterator<Item = &Message> {
        self.list.iter().filter(|m| m.level == Level::Error)
    }

    pub fn clear(&mut self) {
        self.list.clear();
    }

    /// Drops expired notices; call once a frame.
    pub fn tick(&mut self, ctx: &egui::Context) {
        self.now = ctx.input(|i| i.time);
        let now = self.now;
        self.list.retain(|m| m.level == Level::Error || now - m.time < Self::INFO_SECONDS);
        if let Some(next) = self.list.iter().filter(|m| m.level == Level::Info).map(|m| m.time + Self::INFO_SECONDS - now).reduce(f64::min) {
            ctx.request_repaint_after(std::time::Duration::from_secs_f64(next.max(0.05)));
        }
    }

    /// Toasts in the top right corner of `rect`.
    pub fn show(&mut self, ui: &egui::Ui, rect: egui::Rect) {
        if self.list.is_empty() {
            return;
        }
        let mut dismiss = None;
        egui::Area::new(egui::Id::unique("glocal_toasts"))
            .order(egui::Order::Foreground)
            .fixed_pos(rect.right_top() + egui::vec2(-12.0, 12.0))
            .pivot(egui::Align2::RIGHT_TOP)
            .show(ui.ctx(), |ui| {
                ui.set_max_width(420.0);
                for (k, m) in self.list.iter().enumerate().rev() {
                    let (fill, stroke) = match m.level {
                        Level::Error => (Color32::from_rgb(70, 24, 24), Color32::from_rgb(220, 80, 70)),
                        Level::Info => (Color32::from_rgb(28, 44, 60), Color32::from_rgb(90, 150, 210)),
                    };
                    egui::Frame::new().fill(fill).stroke((1.0, stroke)).corner_radius(6.0).inner_margin(8.0).show(ui, |ui| {
                        ui.horizontal(|ui| {
                            let icon = if m.level == Level::Error { "!" } else { "i" };
                            ui.label(RichText::new(icon).color(stroke).strong());
                            ui.add(egui::Label::new(RichText::new(&m.text).color(Color32::WHITE)).wrap());
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
}

fn log_error(text: &str) {
    eprintln!("glocal studio: {text}");
}
