//! A run's progress for the person who started it: a bar on a terminal, a plain line every
//! few seconds otherwise (a batch job, `cosim run … 2>log`), nothing with `--quiet`. Messages
//! printed during the run go through [`Progress::note`], so that the bar never overwrites them.

use std::io::IsTerminal;
use std::time::{Duration, Instant};

/// Seconds between two progress lines when stderr is not a terminal (`COSIM_PROGRESS_EVERY`
/// overrides; a batch job may want a minute).
const LINE_EVERY_S: f64 = 10.0;

enum Shown {
    Bar(indicatif::ProgressBar),
    Lines { every: Duration, next: Instant },
    Quiet,
}

pub struct Progress {
    shown: Shown,
    /// Windows done before this process started them (a restart): not in the rate.
    before: u64,
    windows: u64,
    end_time: f64,
    start: Instant,
}

impl Progress {
    /// Nothing shown, messages still printed (before the window loop starts).
    pub fn quiet() -> Progress {
        Progress {
            shown: Shown::Quiet,
            before: 0,
            windows: 0,
            end_time: 0.0,
            start: Instant::now(),
        }
    }

    /// Progress over `windows` windows to `end_time` (s): a bar on a terminal, lines
    /// otherwise, nothing when `quiet`.
    pub fn new(windows: u64, end_time: f64, quiet: bool) -> Progress {
        let shown = if quiet {
            Shown::Quiet
        } else if std::io::stderr().is_terminal() {
            let b = indicatif::ProgressBar::new(windows);
            b.set_style(
                indicatif::ProgressStyle::with_template(
                    "{spinner} {msg} [{bar:30}] {pos}/{len} windows, ETA {eta}",
                )
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
            );
            Shown::Bar(b)
        } else {
            let every = std::env::var("COSIM_PROGRESS_EVERY")
                .ok()
                .and_then(|s| s.parse::<f64>().ok())
                .filter(|s| s.is_finite() && *s > 0.0)
                .unwrap_or(LINE_EVERY_S);
            let every = Duration::from_secs_f64(every);
            Shown::Lines {
                every,
                next: Instant::now() + every,
            }
        };
        Progress {
            shown,
            before: 0,
            windows,
            end_time,
            start: Instant::now(),
        }
    }

    /// A restarted run continues after window `k`.
    pub fn resume_after(&mut self, k: u64) {
        self.before = k;
        self.start = Instant::now();
        if let Shown::Bar(b) = &self.shown {
            b.set_position(k);
            b.reset_eta();
        }
    }

    /// Window `k` (1-based) has ended at simulated time `t`.
    pub fn window(&mut self, k: u64, t: f64) {
        let elapsed = self.start.elapsed().as_secs_f64();
        let done = k.saturating_sub(self.before);
        match &mut self.shown {
            Shown::Bar(b) => {
                b.set_message(format!("t = {t:.4e} s, {}", rate(done, elapsed)));
                b.set_position(k);
            }
            Shown::Lines { every, next } => {
                if Instant::now() >= *next {
                    *next += *every;
                    let left = self.windows.saturating_sub(k);
                    eprintln!(
                        "{}",
                        line(k, self.windows, t, self.end_time, done, left, elapsed)
                    );
                }
            }
            Shown::Quiet => {}
        }
    }

    /// Print a message without the bar drawing over it.
    pub fn note(&self, msg: &str) {
        match &self.shown {
            Shown::Bar(b) => b.suspend(|| eprintln!("{msg}")),
            _ => eprintln!("{msg}"),
        }
    }

    pub fn finish(&self) {
        if let Shown::Bar(b) = &self.shown {
            b.finish_and_clear();
        }
    }
}

/// `"812 windows/s"`: plain digits, no separators.
fn rate(k: u64, elapsed: f64) -> String {
    if elapsed > 0.0 {
        let r = k as f64 / elapsed;
        if r >= 10.0 {
            format!("{r:.0} windows/s")
        } else {
            format!("{r:.2} windows/s")
        }
    } else {
        "– windows/s".into()
    }
}

/// One progress line: simulated time and share of the run, window `k` of `windows`, the rate
/// over the `done` windows of this process, elapsed time, and the ETA of the `left` ones.
fn line(k: u64, windows: u64, t: f64, end_time: f64, done: u64, left: u64, elapsed: f64) -> String {
    let share = if end_time > 0.0 {
        100.0 * t / end_time
    } else {
        0.0
    };
    let eta = if done > 0 && left > 0 {
        format!("{:.0} s", elapsed * left as f64 / done as f64)
    } else {
        "–".into()
    };
    format!(
        "cosim: t = {t:.4e} s of {end_time:.4e} s ({share:.1} %), window {k} of {windows}, {}, elapsed {elapsed:.0} s, ETA {eta}",
        rate(done, elapsed)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_says_where_the_run_is_in_plain_numbers() {
        let l = line(2500, 10000, 2.5e-3, 1e-2, 2500, 7500, 2.0);
        assert_eq!(
            l,
            "cosim: t = 2.5000e-3 s of 1.0000e-2 s (25.0 %), window 2500 of 10000, 1250 windows/s, elapsed 2 s, ETA 6 s"
        );
        assert_eq!(rate(3, 2.0), "1.50 windows/s");
        assert!(line(0, 10, 0.0, 1.0, 0, 10, 0.0).ends_with("ETA –"));
        // A restart from window 2000: the rate counts this process's 500 windows only.
        assert!(line(2500, 10000, 2.5e-3, 1e-2, 500, 7500, 2.0).contains("250 windows/s"));
    }
}
