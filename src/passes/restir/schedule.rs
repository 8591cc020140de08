//! Which ReSTIR stages a frame dispatches, and on which reservoir slots.
//!
//! Reservoirs live in two or three slots ([`slots`]). A frame writes its initial
//! candidates into a slot other than the previous frame's result, reuses temporally in
//! place (reading the previous slot), ping-pongs spatial rounds between two slots, and
//! shades the last output, which becomes the next frame's previous slot. Once the
//! temporal stage has read the previous slot it is free, so a spatial round may write it;
//! only when the history is taken before spatial reuse and there are two or more rounds
//! does the ping-pong need a third slot. This is a pure function of the frame, the
//! previous slot and the settings, so it is unit-tested here rather than through images.

use crate::shader_data::RestirPush;

/// The most reservoir slots a schedule uses.
pub const MAX_SLOTS: u32 = 3;

/// The reservoir slots `settings` needs: 2 (initial and temporal in one, the previous
/// frame's history in the other, spatial rounds alternating between them), or 3 when
/// the temporal stage's slot must survive two or more spatial rounds.
pub fn slots(settings: &ScheduleSettings) -> u32 {
    crate::plan::reservoir_slots(
        settings.spatial_neighbors,
        settings.spatial_rounds,
        settings.history_before_spatial,
    )
}

/// One stage of a frame, in dispatch order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Stage {
    Initial,
    Temporal,
    Spatial,
    Shade,
}

impl Stage {
    pub const ALL: [Stage; 4] = [
        Stage::Initial,
        Stage::Temporal,
        Stage::Spatial,
        Stage::Shade,
    ];

    /// The profiler scope and pipeline name.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Initial => "initial",
            Stage::Temporal => "temporal",
            Stage::Spatial => "spatial",
            Stage::Shade => "shade",
        }
    }
}

/// The settings the schedule depends on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScheduleSettings {
    pub temporal: bool,
    pub spatial_neighbors: u32,
    pub spatial_rounds: u32,
    /// M, and how many of them one initial dispatch draws (the initial stage is
    /// dispatched ceil(M / per dispatch) times; `aux` is each dispatch's first).
    pub candidates: u32,
    pub candidates_per_dispatch: u32,
    /// The temporal stage's slot (before spatial reuse), not the last one, is what the
    /// next frame reuses.
    pub history_before_spatial: bool,
}

/// One dispatch: a stage and its push constants (`src`, `dst` slots; `aux` is the
/// previous slot for the temporal stage and the round for spatial ones).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dispatch {
    pub stage: Stage,
    pub push: RestirPush,
}

/// The dispatches of frame `frame` (counting warm-up frames) given the slot holding the
/// previous frame's history, and the slot of this frame's history: its final reservoirs,
/// or with `history_before_spatial` the temporal stage's.
/// Frame 0 has no previous frame, whatever `previous` says.
pub fn schedule(
    frame: u32,
    previous: Option<u32>,
    settings: &ScheduleSettings,
) -> (Vec<Dispatch>, u32) {
    let n = slots(settings);
    let previous = previous.filter(|p| frame > 0 && *p < n);
    // `first` holds this frame's initial and temporal reservoirs; `second` is the other
    // slot, the previous history's on frames after the first (dead once the temporal
    // stage has read it).
    let first = (0..n).find(|s| Some(*s) != previous).unwrap_or(0);
    let second = (0..n).find(|s| *s != first).unwrap_or(1);
    let push = |src, dst, aux| RestirPush {
        frame,
        src,
        dst,
        aux,
    };
    let chunk = settings.candidates_per_dispatch.max(1);
    let mut dispatches: Vec<Dispatch> = (0..settings.candidates.max(1))
        .step_by(chunk as usize)
        .map(|m0| Dispatch {
            stage: Stage::Initial,
            push: push(first, first, m0),
        })
        .collect();
    if let (true, Some(p)) = (settings.temporal, previous) {
        dispatches.push(Dispatch {
            stage: Stage::Temporal,
            push: push(first, first, p),
        });
    }
    // Spatial rounds ping-pong between two slots. With the history taken before spatial
    // reuse, `first` must survive the frame: the rounds use the other two (the previous
    // frame's history is no longer needed once the temporal stage has read it); one
    // round needs only `second`.
    let third = (0..n).find(|s| *s != first && *s != second).unwrap_or(2);
    let pair = if settings.history_before_spatial {
        [second, third]
    } else {
        [second, first]
    };
    let mut at = first;
    if settings.spatial_neighbors > 0 {
        for round in 0..settings.spatial_rounds {
            let other = pair[(round % 2) as usize];
            dispatches.push(Dispatch {
                stage: Stage::Spatial,
                push: push(at, other, round),
            });
            at = other;
        }
    }
    dispatches.push(Dispatch {
        stage: Stage::Shade,
        push: push(at, at, 0),
    });
    let history = if settings.history_before_spatial {
        first
    } else {
        at
    };
    (dispatches, history)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(temporal: bool, neighbors: u32, rounds: u32) -> ScheduleSettings {
        ScheduleSettings {
            temporal,
            spatial_neighbors: neighbors,
            spatial_rounds: rounds,
            candidates: 4,
            candidates_per_dispatch: 4,
            history_before_spatial: false,
        }
    }

    #[test]
    fn the_history_can_be_the_reservoir_before_spatial_reuse() {
        let s = ScheduleSettings {
            history_before_spatial: true,
            ..settings(true, 3, 2)
        };
        let mut previous = None;
        for frame in 0..6 {
            let (d, history) = schedule(frame, previous, &s);
            let initial = d[0].push.dst;
            assert_eq!(history, initial, "frame {frame}");
            // Spatial rounds never write the slot that becomes the history.
            for x in d.iter().filter(|x| x.stage == Stage::Spatial) {
                assert_ne!(x.push.dst, history);
            }
            previous = Some(history);
        }
    }

    #[test]
    fn candidates_split_over_initial_dispatches() {
        let s = ScheduleSettings {
            candidates: 10,
            candidates_per_dispatch: 4,
            ..settings(false, 0, 0)
        };
        let (d, _) = schedule(0, None, &s);
        let firsts: Vec<_> = d
            .iter()
            .filter(|d| d.stage == Stage::Initial)
            .map(|d| (d.push.dst, d.push.aux))
            .collect();
        assert_eq!(firsts, [(0, 0), (0, 4), (0, 8)]);
    }

    fn stages(d: &[Dispatch]) -> Vec<Stage> {
        d.iter().map(|d| d.stage).collect()
    }

    #[test]
    fn first_frame_has_no_temporal_stage() {
        let (d, last) = schedule(0, Some(2), &settings(true, 3, 1));
        assert_eq!(stages(&d), [Stage::Initial, Stage::Spatial, Stage::Shade]);
        assert_eq!(
            d[0].push,
            RestirPush {
                frame: 0,
                src: 0,
                dst: 0,
                aux: 0
            }
        );
        assert_eq!(
            d[1].push,
            RestirPush {
                frame: 0,
                src: 0,
                dst: 1,
                aux: 0
            }
        );
        assert_eq!(last, 1);
    }

    #[test]
    fn temporal_reads_the_previous_slot_and_spatial_rounds_ping_pong() {
        let (d, last) = schedule(5, Some(0), &settings(true, 3, 3));
        assert_eq!(
            stages(&d),
            [
                Stage::Initial,
                Stage::Temporal,
                Stage::Spatial,
                Stage::Spatial,
                Stage::Spatial,
                Stage::Shade
            ]
        );
        assert_eq!(
            d[1].push,
            RestirPush {
                frame: 5,
                src: 1,
                dst: 1,
                aux: 0
            }
        );
        // The previous slot (0) is free once the temporal stage has read it.
        let rounds: Vec<_> = d[2..5]
            .iter()
            .map(|d| (d.push.src, d.push.dst, d.push.aux))
            .collect();
        assert_eq!(rounds, [(1, 0, 0), (0, 1, 1), (1, 0, 2)]);
        assert_eq!(
            d[5].push,
            RestirPush {
                frame: 5,
                src: 0,
                dst: 0,
                aux: 0
            }
        );
        assert_eq!(last, 0);
    }

    #[test]
    fn a_third_slot_only_when_the_history_must_survive_two_rounds() {
        let with = |before: bool, neighbors, rounds| ScheduleSettings {
            history_before_spatial: before,
            ..settings(true, neighbors, rounds)
        };
        assert_eq!(slots(&with(false, 0, 1)), 2);
        assert_eq!(slots(&with(true, 0, 3)), 2);
        assert_eq!(slots(&with(false, 3, 1)), 2);
        assert_eq!(slots(&with(false, 3, 4)), 2);
        assert_eq!(slots(&with(true, 3, 1)), 2);
        assert_eq!(slots(&with(true, 3, 2)), 3);
        assert_eq!(slots(&with(true, 3, 0)), 2);
    }

    #[test]
    fn no_spatial_stage_without_neighbours_or_rounds() {
        for s in [settings(true, 0, 2), settings(true, 4, 0)] {
            let (d, last) = schedule(1, Some(1), &s);
            assert_eq!(stages(&d), [Stage::Initial, Stage::Temporal, Stage::Shade]);
            assert_eq!(last, 0);
        }
        let (d, _) = schedule(1, Some(1), &settings(false, 0, 0));
        assert_eq!(stages(&d), [Stage::Initial, Stage::Shade]);
    }

    /// Over many frames and every setting: the previous result is never overwritten
    /// before the temporal stage reads it, stages come in order, and the result slot of
    /// a frame is what the next frame's temporal stage reads.
    #[test]
    fn slots_never_clobber_the_previous_result() {
        for before_spatial in [false, true] {
            for temporal in [false, true] {
                for neighbors in [0, 1, 3] {
                    for rounds in 0..5 {
                        let s = ScheduleSettings {
                            history_before_spatial: before_spatial,
                            ..settings(temporal, neighbors, rounds)
                        };
                        check_frames(&s, temporal, neighbors, rounds);
                    }
                }
            }
        }
    }

    /// Twelve frames of `s`: stages in order; nothing overwrites the previous history
    /// before the temporal stage has read it (nothing at all with the spatial history);
    /// the history slot survives the frame; counts of stages right.
    fn check_frames(s: &ScheduleSettings, temporal: bool, neighbors: u32, rounds: u32) {
        let mut previous = None;
        for frame in 0..12 {
            let (d, history) = schedule(frame, previous, s);
            let mut sorted = stages(&d);
            sorted.sort();
            assert_eq!(sorted, stages(&d), "stages in order");
            assert_eq!(d.last().map(|d| d.stage), Some(Stage::Shade));
            for x in &d {
                assert!(x.push.src < slots(s) && x.push.dst < slots(s));
                assert!(slots(s) <= MAX_SLOTS);
                assert_eq!(x.push.frame, frame);
                // Once the temporal stage has read the previous history (or without one),
                // later stages may write its slot.
                let may_reuse_previous = x.stage >= Stage::Spatial;
                if frame > 0 && !may_reuse_previous {
                    assert_ne!(Some(x.push.dst), previous, "{s:?} frame {frame}");
                }
                match x.stage {
                    Stage::Temporal => assert_eq!(Some(x.push.aux), previous),
                    Stage::Spatial => assert_ne!(x.push.src, x.push.dst),
                    _ => assert_eq!(x.push.src, x.push.dst),
                }
            }
            // After the stage that produced it, nothing writes the history slot.
            let producer = if s.history_before_spatial {
                d.iter().rposition(|x| x.stage <= Stage::Temporal)
            } else {
                Some(d.len() - 1)
            };
            if let Some(p) = producer {
                assert!(d[p + 1..]
                    .iter()
                    .all(|x| x.push.dst != history || x.stage == Stage::Shade));
            }
            let temporal_ran = d.iter().any(|x| x.stage == Stage::Temporal);
            assert_eq!(temporal_ran, temporal && frame > 0);
            let spatial = d.iter().filter(|x| x.stage == Stage::Spatial).count();
            let want = if neighbors > 0 { rounds as usize } else { 0 };
            assert_eq!(spatial, want);
            if !s.history_before_spatial {
                assert_eq!(d.last().map(|d| d.push.src), Some(history));
            }
            previous = Some(history);
        }
    }
}
