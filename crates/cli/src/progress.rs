//! Progress display on stderr (indicatif), only when stderr is a terminal.
//!
//! Each long step (setup, evaluation, the direct check) shows a spinner
//! with its name and the elapsed time; the setup's steps (parameters,
//! tree, operators, layout) and the evaluation (the FMM passes) report
//! their progress, and their spinner becomes a bar with an ETA; `sweep` shows a bar over its
//! configurations. When
//! stderr is redirected (a pipe, a file, a test harness, a sweep's child
//! process), or with `--quiet` ([`set_quiet`]), nothing is drawn at all.

use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use std::sync::{Arc, Mutex};

use ferrofmm_fmm::{EvalProgress, ProgressFn, SetupProgress, SetupStep};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// `--quiet`: no progress, no report (errors and warnings still print).
static QUIET: AtomicBool = AtomicBool::new(false);

/// Silence progress (and, through [`quiet`], the report) for the rest of
/// the process: `--quiet`.
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, Ordering::Relaxed);
}

/// Whether `--quiet` was given.
pub fn quiet() -> bool {
    QUIET.load(Ordering::Relaxed)
}

/// Draw target: stderr when it is a terminal and not `--quiet`, hidden
/// otherwise.
fn target() -> ProgressDrawTarget {
    if !quiet() && std::io::stderr().is_terminal() {
        ProgressDrawTarget::stderr()
    } else {
        ProgressDrawTarget::hidden()
    }
}

/// A spinner for one step; cleared when finished or dropped.
pub struct Stage(ProgressBar);

/// Start a spinner labelled `message`.
pub fn stage(message: impl Into<String>) -> Stage {
    let bar = ProgressBar::with_draw_target(None, target());
    if !bar.is_hidden() {
        bar.set_style(
            ProgressStyle::with_template("{spinner} {msg} [{elapsed}]")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        bar.set_message(message.into());
        bar.enable_steady_tick(Duration::from_millis(120));
    }
    Stage(bar)
}

impl Stage {
    /// A progress callback for a build ([`ferrofmm_fmm::FmmBuilder::setup_progress`]):
    /// each step (choosing the parameters, the tree, the operators, the
    /// layout) turns the spinner into a bar of its own, labelled with the
    /// step, with the step's elapsed time and an ETA
    /// (`[elapsed < remaining]`); at 1e8 points each takes tens of
    /// seconds, and the operators at high orders minutes.
    pub fn setup_progress(&self) -> impl Fn(SetupProgress) + Send + Sync + 'static {
        let bar = self.0.clone();
        let current: Mutex<Option<SetupStep>> = Mutex::new(None);
        move |p: SetupProgress| {
            // After the setup (an order raised by the verification builds
            // operators again) the stage is gone: nothing to draw.
            if bar.is_hidden() || bar.is_finished() || p.total == 0 {
                return;
            }
            let mut step = current.lock().unwrap_or_else(|e| e.into_inner());
            if *step != Some(p.step) {
                *step = Some(p.step);
                bar.set_style(bar_style());
                bar.set_message(setup_label(p.step));
                bar.reset();
            }
            bar.set_length(p.total);
            bar.set_position(p.done);
        }
    }

    /// A progress callback for an evaluation (the FMM passes report their
    /// work done), shown as the precomputation's: a bar labelled `message`
    /// with the time left. Each evaluation starts the bar again.
    pub fn eval_progress(&self, message: String) -> Arc<ProgressFn> {
        let to_bar = self.to_bar(message);
        Arc::new(move |p: EvalProgress| to_bar(p.done, p.total))
    }

    /// Show `done / total` units: the first report turns the spinner into
    /// a bar labelled `message`; a report of 0 done restarts the estimate.
    fn to_bar(&self, message: String) -> impl Fn(u64, u64) + Send + Sync + 'static {
        let bar = self.0.clone();
        let switched = AtomicBool::new(false);
        move |done: u64, total: u64| {
            if bar.is_hidden() || total == 0 {
                return;
            }
            if !switched.swap(true, Ordering::Relaxed) {
                bar.set_style(bar_style());
                bar.set_message(message.clone());
            }
            if done == 0 {
                bar.reset_eta();
            }
            bar.set_length(total);
            bar.set_position(done);
        }
    }
}

/// A step's bar: label, bar, percent, `[elapsed < remaining]`.
fn bar_style() -> ProgressStyle {
    ProgressStyle::with_template("{msg} {bar:30} {percent:>3}% [{elapsed} < {eta}]")
        .unwrap_or_else(|_| ProgressStyle::default_bar())
}

/// The label of a build step's bar.
fn setup_label(step: SetupStep) -> String {
    let what = match step {
        SetupStep::Tuning => "choosing parameters",
        SetupStep::Tree => "tree",
        SetupStep::Operators => "M2L operators",
        SetupStep::Layout => "layout",
    };
    format!("setup: {what}")
}

impl Drop for Stage {
    fn drop(&mut self) {
        self.0.finish_and_clear();
    }
}

/// A bar over `len` steps (cleared when dropped by the caller with
/// `finish_and_clear`).
pub fn bar(len: u64) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(Some(len), target());
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} [{elapsed} < {eta}] {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar
}

/// Run `f` under a spinner labelled `message`.
pub fn with_stage<R>(message: impl Into<String>, f: impl FnOnce() -> R) -> R {
    let _stage = stage(message);
    f()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With `--quiet` nothing is drawn, terminal or not, and the progress
    /// callbacks leave the (hidden) bar alone; without it, bars are drawn
    /// only when stderr is a terminal (under a test harness it usually is
    /// not; the integration tests check the empty stderr of real runs).
    #[test]
    fn quiet_or_no_terminal_draws_nothing() {
        set_quiet(true);
        let s = stage("setup");
        assert!(s.0.is_hidden());
        assert!(bar(10).is_hidden());
        let eval = s.eval_progress("evaluating".into());
        eval(EvalProgress { done: 1, total: 2 });
        let setup = s.setup_progress();
        setup(SetupProgress {
            step: SetupStep::Tree,
            done: 1,
            total: 2,
        });
        assert_eq!((s.0.position(), s.0.length()), (0, None));
        set_quiet(false);
        assert_eq!(
            stage("setup").0.is_hidden(),
            !std::io::stderr().is_terminal()
        );
    }
}
