//! The command line's progress bars: [`tomograf_scene::Progress`] drawn with indicatif.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::sync::Mutex;
use tomograf_scene::Progress;

/// A bar per stage, on stderr; a stage of fewer than two steps draws none.
#[derive(Default)]
pub struct Bar {
    bar: Mutex<Option<ProgressBar>>,
}

impl Bar {
    fn with(&self, f: impl FnOnce(&ProgressBar)) {
        if let Some(b) = self.bar.lock().expect("progress bar lock").as_ref() {
            f(b)
        }
    }
}

impl Progress for Bar {
    fn start(&self, label: &str, total: u64, done: u64) {
        let bar = ProgressBar::new(total).with_position(done).with_style(
            ProgressStyle::with_template(&format!(
                "{{spinner}} {label} {{pos}}/{{len}} [{{bar:30}}] {{elapsed}} (eta {{eta}}) {{msg}}"
            ))
            .expect("valid template")
            .progress_chars("=> "),
        );
        if total < 2 {
            bar.set_draw_target(ProgressDrawTarget::hidden());
        }
        if let Some(old) = self.bar.lock().expect("progress bar lock").replace(bar) {
            old.finish_and_clear();
        }
    }

    fn set(&self, done: u64) {
        self.with(|b| b.set_position(done))
    }

    fn set_message(&self, message: &str) {
        self.with(|b| b.set_message(message.to_string()))
    }

    fn inc(&self) {
        self.with(|b| b.inc(1))
    }

    fn finish(&self) {
        if let Some(b) = self.bar.lock().expect("progress bar lock").take() {
            b.finish_and_clear();
        }
    }

    fn note(&self, message: &str) {
        let line = message.to_string();
        match self.bar.lock().expect("progress bar lock").as_ref() {
            Some(b) => b.suspend(|| eprintln!("{line}")),
            None => eprintln!("{line}"),
        }
    }
}
