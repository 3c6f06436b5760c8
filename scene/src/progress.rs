//! How long jobs report how far they are, without drawing anything themselves: the
//! command line draws a progress bar (`src/progress.rs`), the Python bridge may call back
//! into Python, and tests pass [`Silent`]. One stage at a time: [`Progress::start`] names
//! it and gives its length, [`Progress::set`] and [`Progress::inc`] move it, [`Progress::finish`] ends it.
//! Calls may come from several threads of one job (items of a data set are made in
//! parallel), hence `Sync`.

/// A receiver of progress reports. Every method has a default that does nothing, except
/// [`Progress::note`], which prints to stderr, and [`Progress::warn`], which notes.
pub trait Progress: Sync {
    /// A new stage: `label` says what is counted ("view", "item", "iteration"), `total`
    /// how many there are, `done` how many were finished before (a resumed job).
    fn start(&self, label: &str, total: u64, done: u64) {
        let _ = (label, total, done);
    }
    /// `done` of the stage's steps are finished.
    fn set(&self, done: u64) {
        let _ = done;
    }
    /// What the stage is at (an item's index, a loss), shown beside the count.
    fn set_message(&self, message: &str) {
        let _ = message;
    }
    /// One more step is finished.
    fn inc(&self) {}
    /// The stage is over.
    fn finish(&self) {}
    /// A line the user may want to read: what a step did or is about to do.
    fn note(&self, message: &str) {
        eprintln!("{message}");
    }
    /// A line the user should read: something probably not meant (a source inside the
    /// volume, views missing it, a clipped detector). By default, a note.
    fn warn(&self, message: &str) {
        self.note(message);
    }
}

/// Reports nothing, notes included (tests, batch callers that log their own way).
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Progress for Silent {
    fn note(&self, _message: &str) {}
}
