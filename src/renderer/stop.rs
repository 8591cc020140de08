//! When an image stops: the rule asked for (a target error, a time limit) and why it
//! ended.

use std::time::Duration;

/// When an image stops before its frame count.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StopRule {
    /// Stop once the relative standard error ([`super::film::relative_error`]) is at most
    /// this, with at least [`MIN_ESTIMATES`] independent estimates behind it.
    pub target_error: Option<f64>,
    /// Stop before a frame that would end after this much wall-clock time of the
    /// image's measured frames (warm-up and set-up are not counted); at least one frame
    /// is always rendered.
    pub time_limit: Option<Duration>,
}

impl StopRule {
    /// Whether a rule is set: the frame count is then only an upper bound of
    /// [`MAX_STOP_RULE_FRAMES`].
    pub fn is_set(&self) -> bool {
        self.target_error.is_some() || self.time_limit.is_some()
    }
}

/// Independent estimates (frames, or batches) needed before a target error is trusted:
/// the per-pixel variances come from at least this many values.
pub const MIN_ESTIMATES: u32 = 8;

/// Most frames of one image under a stop rule.
pub const MAX_STOP_RULE_FRAMES: u32 = 1_000_000;

/// Why an image ended.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum StopReason {
    /// All its frames were rendered.
    #[default]
    Done,
    TargetError,
    TimeLimit,
    /// The user interrupted (SIGINT): the image holds the frames done so far.
    Interrupted,
}

impl StopReason {
    pub fn describe(self) -> &'static str {
        match self {
            StopReason::Done => "all frames rendered",
            StopReason::TargetError => "target error reached",
            StopReason::TimeLimit => "time limit reached",
            StopReason::Interrupted => "interrupted",
        }
    }
}
