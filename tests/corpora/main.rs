//! The corpus tests: every model of the Khronos glTF validator's assets and of Debian's
//! `assimp-testmodels` bakes, or is refused in one line, within a time limit per model.
//!
//! A test binary of their own, not modules of `end_to_end`: their limits are wall time, so
//! they must not share the CPUs with other tests (next to the end-to-end tests a 32 s draft
//! bake took past its 60 s limit), and they take [`one_at_a_time`] so that they do not share
//! them with each other either.

#[path = "../end_to_end/common.rs"]
mod common;

mod corpus;
mod real_corpus;

/// Held by each corpus test for its whole run.
fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    // A failed test poisons the lock; the next one still runs alone.
    LOCK.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}
