//! Deterministic work counters (`shaders/include/counters.glsl`): what a pass did, counted
//! on the GPU, per pass slot. Timings on shared machines are noise; work is not: the same
//! scene, seed and device give the same counts, so tests pin them (`tests/suite/contracts/counters.rs`)
//! and `nimbus bench` compares them with a stored baseline.
//!
//! The counters live in the stats buffer after its [`STAT_COUNT`] words: per slot,
//! [`COUNTER_COUNT`] counters of two u32 each (low word first); after every slot's sums,
//! per slot, each counter's largest value in one invocation (one u32 each: on a GPU a
//! dispatch lasts as long as its slowest lane, which the sums average away; a runaway
//! walk in one lane in a million shows there and nowhere else). A pipeline counts only when
//! it is specialized with `SC_COUNTERS` (see [`specialization`]); otherwise the counting
//! code compiles out and the words stay 0.

use std::fmt::Write as _;

use nimbus_gpu::SpecValue;

use super::bindings::STAT_COUNT;
use super::features::{COUNTER_COUNT, COUNTER_SLOTS, SC_ID_COUNTERS, SC_ID_COUNTER_SLOT};

/// Counter names in the order of `CTR_*` in counters.glsl, with what each counts.
pub const NAMES: [(&str, &str); COUNTER_COUNT as usize] = [
    (
        "samples",
        "camera samples (paths from the camera; ReSTIR: pixels of the pass)",
    ),
    (
        "steps",
        "tracking steps outside shadow rays (cells, super-voxels, blocks, march samples)",
    ),
    (
        "density",
        "density fetches (trilinear lookups of 8 texels, filtered march samples)",
    ),
    (
        "majorant",
        "majorant fetches (super-voxel bounds, piecewise-constant voxels)",
    ),
    (
        "collisions",
        "tentative collisions of delta, decomposition and ratio tracking",
    ),
    (
        "shadow_rays",
        "shadow rays (transmittance estimates of a segment)",
    ),
    ("shadow_steps", "tracking steps inside shadow rays"),
    ("bvh_nodes", "mesh BVH nodes visited"),
];

/// u32 words of the stats buffer: the fixed stats, the counters' sums of every slot, then
/// their per-invocation maxima.
pub const STATS_WORDS: usize = STAT_COUNT + 3 * (COUNTER_COUNT * COUNTER_SLOTS) as usize;

/// The stats word of slot `slot`'s largest per-invocation value of counter `c`.
fn longest_word(slot: usize, c: usize) -> usize {
    STAT_COUNT + 2 * (COUNTER_COUNT * COUNTER_SLOTS) as usize + slot * COUNTER_COUNT as usize + c
}

/// The specialization constants that make a pipeline count into pass slot `slot`, or
/// none when the render does not count.
pub fn specialization(slot: Option<u32>) -> Vec<(u32, SpecValue)> {
    match slot {
        Some(s) => vec![
            (SC_ID_COUNTERS, SpecValue::Bool(true)),
            (SC_ID_COUNTER_SLOT, SpecValue::U32(s.min(COUNTER_SLOTS - 1))),
        ],
        // Said explicitly: every constant a shader declares is set (nimbus_gpu::spirv).
        None => vec![
            (SC_ID_COUNTERS, SpecValue::Bool(false)),
            (SC_ID_COUNTER_SLOT, SpecValue::U32(0)),
        ],
    }
}

/// One pass slot's counts.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SlotCounts {
    /// The pass stage that counted (`baseline`, `restir/initial`, ...).
    pub label: String,
    pub counts: [u64; COUNTER_COUNT as usize],
    /// Each counter's largest value in one invocation (`samples`: the most camera samples
    /// one invocation took).
    pub longest: [u64; COUNTER_COUNT as usize],
}

impl SlotCounts {
    /// Counter `name` (one of [`NAMES`]); 0 for an unknown name.
    pub fn get(&self, name: &str) -> u64 {
        NAMES
            .iter()
            .position(|(n, _)| *n == name)
            .map_or(0, |i| self.counts[i])
    }

    /// Counter `name` per camera sample (0 without samples).
    pub fn per_sample(&self, name: &str) -> f64 {
        let samples = self.get("samples");
        if samples == 0 {
            return 0.0;
        }
        self.get(name) as f64 / samples as f64
    }
}

/// What every counting stage of a render did, and the dispatches it took.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WorkCounts {
    pub slots: Vec<SlotCounts>,
    /// Compute dispatches recorded over the measured frames.
    pub dispatches: u64,
    /// Frames the counts cover.
    pub frames: u32,
}

impl WorkCounts {
    /// Reads the counters of the slots named `labels` (slot i is `labels[i]`) from the
    /// stats words.
    pub fn from_stats(stats: &[u32], labels: &[&str], dispatches: u64, frames: u32) -> Self {
        let slots = labels
            .iter()
            .enumerate()
            .take(COUNTER_SLOTS as usize)
            .map(|(slot, label)| {
                let mut counts = [0u64; COUNTER_COUNT as usize];
                let mut longest = [0u64; COUNTER_COUNT as usize];
                for (c, count) in counts.iter_mut().enumerate() {
                    let at = STAT_COUNT + 2 * (slot * COUNTER_COUNT as usize + c);
                    let lo = stats.get(at).copied().unwrap_or(0);
                    let hi = stats.get(at + 1).copied().unwrap_or(0);
                    *count = u64::from(lo) | (u64::from(hi) << 32);
                    longest[c] = u64::from(stats.get(longest_word(slot, c)).copied().unwrap_or(0));
                }
                SlotCounts {
                    label: (*label).to_string(),
                    counts,
                    longest,
                }
            })
            .collect();
        WorkCounts {
            slots,
            dispatches,
            frames,
        }
    }

    /// The slot labelled `label`.
    pub fn slot(&self, label: &str) -> Option<&SlotCounts> {
        self.slots.iter().find(|s| s.label == label)
    }

    /// Dispatches per frame.
    pub fn dispatches_per_frame(&self) -> f64 {
        self.dispatches as f64 / f64::from(self.frames.max(1))
    }

    /// A fixed-width table: per stage, each counter per camera sample, and the totals.
    pub fn table(&self) -> String {
        let mut out = String::new();
        let _ = write!(out, "{:<22}", "work per sample");
        for (name, _) in NAMES.iter().skip(1) {
            let _ = write!(out, " {:>12}", name);
        }
        let _ = writeln!(out, " {:>12}", "samples");
        for s in &self.slots {
            let _ = write!(out, "{:<22}", s.label);
            for (name, _) in NAMES.iter().skip(1) {
                let _ = write!(out, " {:>12.2}", s.per_sample(name));
            }
            let _ = writeln!(out, " {:>12}", s.get("samples"));
        }
        // The tail: what the busiest invocation did (at 1 spp, one path), which decides a
        // GPU dispatch's time where the mean per sample is small.
        let _ = write!(out, "{:<22}", "longest invocation");
        for (name, _) in NAMES.iter().skip(1) {
            let _ = write!(out, " {:>12}", name);
        }
        let _ = writeln!(out, " {:>12}", "samples");
        for s in &self.slots {
            let _ = write!(out, "{:<22}", s.label);
            for v in s.longest.iter().skip(1) {
                let _ = write!(out, " {:>12}", v);
            }
            let _ = writeln!(out, " {:>12}", s.longest[0]);
        }
        let _ = writeln!(
            out,
            "dispatches per frame: {:.2} ({} over {} frame(s))",
            self.dispatches_per_frame(),
            self.dispatches,
            self.frames
        );
        out
    }

    /// The counts as JSON: per stage, totals and per-sample values of every counter.
    pub fn json(&self) -> serde_json::Value {
        let slots: Vec<serde_json::Value> = self
            .slots
            .iter()
            .map(|s| {
                let mut totals = serde_json::Map::new();
                let mut per = serde_json::Map::new();
                let mut longest = serde_json::Map::new();
                for (i, (name, _)) in NAMES.iter().enumerate() {
                    totals.insert((*name).into(), s.counts[i].into());
                    per.insert((*name).into(), s.per_sample(name).into());
                    longest.insert((*name).into(), s.longest[i].into());
                }
                serde_json::json!({
                    "stage": s.label,
                    "totals": totals,
                    "per_sample": per,
                    "longest_invocation": longest,
                })
            })
            .collect();
        serde_json::json!({
            "stages": slots,
            "dispatches": self.dispatches,
            "frames": self.frames,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counters_are_read_as_64_bit_pairs_per_slot() {
        let mut stats = vec![0u32; STATS_WORDS];
        // Slot 1, counter 2 ("density"): 5 * 2^32 + 7.
        let at = STAT_COUNT + 2 * (COUNTER_COUNT as usize + 2);
        stats[at] = 7;
        stats[at + 1] = 5;
        // Slot 1, samples: 2.
        stats[STAT_COUNT + 2 * COUNTER_COUNT as usize] = 2;
        let w = WorkCounts::from_stats(&stats, &["a", "b"], 6, 3);
        assert_eq!(w.slots.len(), 2);
        assert_eq!(
            w.slot("b").map(|s| s.get("density")),
            Some((5u64 << 32) + 7)
        );
        assert_eq!(
            w.slot("b").map(|s| s.per_sample("density")),
            Some(((5u64 << 32) + 7) as f64 / 2.0)
        );
        assert_eq!(w.slot("a").map(|s| s.per_sample("density")), Some(0.0));
        assert_eq!(w.dispatches_per_frame(), 2.0);
    }

    #[test]
    fn the_longest_invocation_is_read_after_every_slot_sum() {
        let mut stats = vec![0u32; STATS_WORDS];
        // Slot 2's longest collisions (counter 4): after the 2 x 8 x 4 words of sums.
        let at = STAT_COUNT + 2 * (COUNTER_COUNT * COUNTER_SLOTS) as usize + 2 * 8 + 4;
        // Slot 3 (the last of 4) follows it.
        assert_eq!(at, STATS_WORDS - 2 * COUNTER_COUNT as usize + 4);
        stats[at] = 65_535;
        let w = WorkCounts::from_stats(&stats, &["a", "b", "c"], 1, 1);
        assert_eq!(w.slot("c").map(|s| s.longest[4]), Some(65_535));
        assert_eq!(w.slot("c").map(|s| s.get("collisions")), Some(0));
        assert_eq!(w.slot("b").map(|s| s.longest[4]), Some(0));
        let table = w.table();
        assert!(table.contains("longest invocation"), "{table}");
        assert!(table.contains("65535"), "{table}");
        let json = w.json();
        assert_eq!(
            json["stages"][2]["longest_invocation"]["collisions"],
            65_535
        );
    }
}
