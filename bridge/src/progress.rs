//! [`tomograf_scene::Progress`] for Python: reports go to an optional callable, notes are
//! collected for the caller, and warnings are raised as `UserWarning`s once the job is back
//! on the Python side.

use pyo3::exceptions::PyUserWarning;
use pyo3::prelude::*;
use std::sync::Mutex;
use tomograf_scene::Progress;

/// Calls `callback(stage, done, total, message)` on every report (with the GIL taken for
/// the call only); the first exception it raises is kept and re-raised by [`finish`].
pub struct PyProgress {
    callback: Option<Py<PyAny>>,
    state: Mutex<State>,
}

#[derive(Default)]
struct State {
    stage: String,
    done: u64,
    total: u64,
    message: String,
    notes: Vec<String>,
    warnings: Vec<String>,
    error: Option<PyErr>,
}

impl PyProgress {
    pub fn new(callback: Option<Py<PyAny>>) -> Self {
        Self {
            callback,
            state: Mutex::new(State::default()),
        }
    }

    fn update(&self, f: impl FnOnce(&mut State)) {
        let mut s = self.state.lock().expect("progress lock");
        f(&mut s);
        let Some(cb) = &self.callback else {
            return;
        };
        if s.error.is_some() {
            return;
        }
        let args = (s.stage.clone(), s.done, s.total, s.message.clone());
        if let Err(e) = Python::attach(|py| cb.call1(py, args).map(|_| ())) {
            s.error = Some(e);
        }
    }

    /// Re-raises the callback's exception, raises the warnings as `UserWarning`s, and
    /// returns the notes and warnings in the order they came.
    pub fn finish(self, py: Python<'_>) -> PyResult<Vec<String>> {
        let s = self.state.into_inner().expect("progress lock");
        if let Some(e) = s.error {
            return Err(e);
        }
        for n in &s.warnings {
            PyErr::warn(
                py,
                &py.get_type::<PyUserWarning>(),
                &std::ffi::CString::new(n.as_str())?,
                1,
            )?;
        }
        Ok(s.notes)
    }
}

impl Progress for PyProgress {
    fn start(&self, label: &str, total: u64, done: u64) {
        self.update(|s| {
            s.stage = label.to_string();
            s.total = total;
            s.done = done;
            s.message.clear();
        })
    }

    fn set(&self, done: u64) {
        self.update(|s| s.done = done)
    }

    fn set_message(&self, message: &str) {
        self.update(|s| s.message = message.to_string())
    }

    fn inc(&self) {
        self.update(|s| s.done += 1)
    }

    fn note(&self, message: &str) {
        let mut s = self.state.lock().expect("progress lock");
        s.notes.push(message.to_string());
    }

    fn warn(&self, message: &str) {
        let mut s = self.state.lock().expect("progress lock");
        s.notes.push(message.to_string());
        s.warnings.push(message.to_string());
    }
}
