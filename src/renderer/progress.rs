//! Progress of a long render on stderr: a bar on a terminal, and without one (farm and
//! CI logs, where a bar draws nothing) a plain line every few seconds.

use std::io::IsTerminal as _;
use std::time::{Duration, Instant};

/// Seconds between progress lines when stderr is not a terminal (default 5); the
/// environment variable `NIMBUS_PROGRESS_SECONDS` changes it.
pub const PROGRESS_SECONDS_VAR: &str = "NIMBUS_PROGRESS_SECONDS";

/// What the render reports with each step.
#[derive(Clone, Copy, Debug, Default)]
pub struct Status {
    /// Frames done of this image, and how many it has at most (None: until a stop rule).
    pub frames: u32,
    pub frames_total: Option<u32>,
    /// The scene frame being rendered (frame mode) and its position in the range.
    pub scene_frame: Option<(u32, usize, usize)>,
    /// The latest relative standard error estimate, if there is one.
    pub rel_error: Option<f64>,
}

/// A progress bar that appears only once a render has taken more than a second, or
/// plain lines without a terminal.
pub struct Progress {
    mode: Mode,
    start: Instant,
}

enum Mode {
    Off,
    Bar(indicatif::ProgressBar),
    Lines { every: Duration, last: Instant },
}

impl Progress {
    /// `enabled` false shows nothing; otherwise a bar on a terminal, else lines.
    pub fn new(enabled: bool) -> Self {
        let mode = if !enabled {
            Mode::Off
        } else if std::io::stderr().is_terminal() {
            let bar = indicatif::ProgressBar::with_draw_target(
                None,
                indicatif::ProgressDrawTarget::hidden(),
            );
            if let Ok(style) = indicatif::ProgressStyle::with_template(
                "{msg} [{bar:30}] {pos}/{len} frames, {elapsed} elapsed, ETA {eta}",
            ) {
                bar.set_style(style.progress_chars("=> "));
            }
            bar.set_message("rendering");
            Mode::Bar(bar)
        } else {
            let seconds = std::env::var(PROGRESS_SECONDS_VAR)
                .ok()
                .and_then(|v| v.trim().parse::<f64>().ok())
                .filter(|s| s.is_finite() && *s >= 0.0)
                .unwrap_or(5.0);
            Mode::Lines {
                every: Duration::from_secs_f64(seconds),
                last: Instant::now(),
            }
        };
        Self {
            mode,
            start: Instant::now(),
        }
    }

    /// Reports one finished frame.
    pub fn tick(&mut self, status: &Status) {
        let elapsed = self.start.elapsed();
        match &mut self.mode {
            Mode::Off => {}
            Mode::Bar(bar) => {
                if bar.is_hidden() && elapsed > Duration::from_secs(1) {
                    bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
                }
                bar.set_length(u64::from(status.frames_total.unwrap_or(status.frames)));
                bar.set_position(u64::from(status.frames));
                bar.set_message(message(status));
            }
            Mode::Lines { every, last } => {
                if last.elapsed() >= *every {
                    *last = Instant::now();
                    eprintln!("{}", line(status, elapsed));
                }
            }
        }
    }

    pub fn finish(&self) {
        if let Mode::Bar(bar) = &self.mode {
            bar.finish_and_clear();
        }
    }
}

/// The bar's message: the frame of a range and the error estimate.
fn message(status: &Status) -> String {
    let mut m = String::from("rendering");
    if let Some((frame, i, n)) = status.scene_frame {
        m = format!("frame {frame} ({}/{n})", i + 1);
    }
    if let Some(e) = status.rel_error {
        m.push_str(&format!(", error {e:.4}"));
    }
    m
}

/// One progress line: `progress: frame 3 (2/5), 12/64 frames (19%), error 0.0521,
/// 3.1 s elapsed, ETA 13 s`.
pub fn line(status: &Status, elapsed: Duration) -> String {
    let mut parts = Vec::new();
    if let Some((frame, i, n)) = status.scene_frame {
        parts.push(format!("frame {frame} ({}/{n})", i + 1));
    }
    let secs = elapsed.as_secs_f64();
    match status.frames_total {
        Some(total) if total > 0 => {
            let done = f64::from(status.frames) / f64::from(total);
            parts.push(format!(
                "{}/{total} frames ({:.0}%)",
                status.frames,
                100.0 * done
            ));
            if status.scene_frame.is_none() && done > 0.0 {
                parts.push(format!(
                    "{secs:.1} s elapsed, ETA {:.0} s",
                    secs * (1.0 - done) / done
                ));
            } else {
                parts.push(format!("{secs:.1} s elapsed"));
            }
        }
        _ => {
            parts.push(format!("{} frames", status.frames));
            parts.push(format!("{secs:.1} s elapsed"));
        }
    }
    if let Some(e) = status.rel_error {
        parts.push(format!("error {e:.4}"));
    }
    format!("progress: {}", parts.join(", "))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_names_frames_error_and_time() {
        let status = Status {
            frames: 16,
            frames_total: Some(64),
            scene_frame: None,
            rel_error: Some(0.0521),
        };
        let l = line(&status, Duration::from_secs(4));
        assert_eq!(
            l,
            "progress: 16/64 frames (25%), 4.0 s elapsed, ETA 12 s, error 0.0521"
        );
        let status = Status {
            frames: 3,
            frames_total: None,
            scene_frame: Some((7, 1, 4)),
            rel_error: None,
        };
        assert_eq!(
            line(&status, Duration::from_millis(1500)),
            "progress: frame 7 (2/4), 3 frames, 1.5 s elapsed"
        );
    }
}
