//! Pure checks of tick conversion, statistics and the Chrome trace writer.

use nimbus_gpu::{summarize, ticks_to_ns, write_chrome_trace, ScopeResult};

fn scope(label: &str, begin_ns: f64, end_ns: f64, children: Vec<ScopeResult>) -> ScopeResult {
    ScopeResult {
        label: label.to_owned(),
        begin_ns,
        end_ns,
        children,
    }
}

#[test]
fn ticks_are_masked_and_scaled() {
    assert_eq!(ticks_to_ns(100, 350, 64, 1.0), 250.0);
    assert_eq!(ticks_to_ns(100, 350, 64, 2.5), 625.0);
    // Bits above the valid ones are garbage and must be ignored.
    let garbage = 0xABCu64 << 36;
    assert_eq!(ticks_to_ns(garbage | 10, garbage | 30, 36, 1.0), 20.0);
    assert_eq!(ticks_to_ns(10, (0xFFu64 << 40) | 30, 36, 1.0), 20.0);
}

#[test]
fn wrapped_counters_give_the_elapsed_time() {
    let mask36 = (1u64 << 36) - 1;
    assert_eq!(ticks_to_ns(mask36 - 4, 5, 36, 1.0), 10.0);
    assert_eq!(ticks_to_ns(u64::MAX - 1, 3, 64, 1.0), 5.0);
    assert_eq!(ticks_to_ns(7, 7, 36, 1.0), 0.0);
    assert_eq!(ticks_to_ns(1, 2, 0, 1.0), 0.0);
}

#[test]
fn summarize_takes_medians_of_odd_and_even_counts() {
    let frame = |outer_ms: f64, inner_ms: f64| {
        vec![scope(
            "frame",
            0.0,
            outer_ms * 1e6,
            vec![scope("rm", 0.0, inner_ms * 1e6, vec![])],
        )]
    };
    let odd = [frame(3.0, 1.0), frame(1.0, 0.5), frame(2.0, 0.75)];
    let stats = summarize(&odd);
    let labels: Vec<&str> = stats.iter().map(|s| s.label.as_str()).collect();
    assert_eq!(labels, ["frame", "frame/rm"]);
    assert_eq!(stats[0].samples, 3);
    assert!((stats[0].median_ms - 2.0).abs() < 1e-12);
    assert!((stats[0].min_ms - 1.0).abs() < 1e-12);
    assert!((stats[0].max_ms - 3.0).abs() < 1e-12);
    assert!((stats[0].mean_ms - 2.0).abs() < 1e-12);
    assert!((stats[1].median_ms - 0.75).abs() < 1e-12);

    let even = [
        frame(4.0, 1.0),
        frame(1.0, 1.0),
        frame(2.0, 1.0),
        frame(3.0, 1.0),
    ];
    let stats = summarize(&even);
    assert_eq!(stats[0].samples, 4);
    assert!((stats[0].median_ms - 2.5).abs() < 1e-12);
    assert!((stats[0].mean_ms - 2.5).abs() < 1e-12);
    assert!(summarize(&[]).is_empty());
}

#[test]
fn summarize_keeps_first_seen_order_across_frames() {
    let frames = [
        vec![scope("a", 0.0, 1.0, vec![])],
        vec![scope("b", 0.0, 1.0, vec![]), scope("a", 1.0, 2.0, vec![])],
    ];
    let stats = summarize(&frames);
    let labels: Vec<(&str, usize)> = stats
        .iter()
        .map(|s| (s.label.as_str(), s.samples))
        .collect();
    assert_eq!(labels, [("a", 2), ("b", 1)]);
}

#[test]
fn chrome_trace_is_json_with_frames_laid_end_to_end() {
    let frames = vec![
        vec![scope(
            "frame",
            0.0,
            2000.0,
            vec![scope("quote \" and \\ and\ttab", 500.0, 1500.0, vec![])],
        )],
        vec![scope("frame", 0.0, 3000.0, vec![])],
    ];
    let mut out = Vec::new();
    write_chrome_trace(&frames, &mut out).expect("write");
    let json: serde_json::Value = serde_json::from_slice(&out).expect("valid JSON");
    let events = json["traceEvents"].as_array().expect("traceEvents array");
    assert_eq!(events.len(), 3);
    let field = |i: usize, key: &str| events[i][key].as_f64().expect(key);
    assert_eq!(events[0]["name"], "frame");
    assert_eq!(events[0]["ph"], "X");
    assert_eq!((field(0, "ts"), field(0, "dur")), (0.0, 2.0));
    assert_eq!(events[1]["name"], "quote \" and \\ and\ttab");
    assert_eq!((field(1, "ts"), field(1, "dur")), (0.5, 1.0));
    // The second frame starts where the first ended (2 µs).
    assert_eq!((field(2, "ts"), field(2, "dur")), (2.0, 3.0));
    assert_eq!(events[2]["pid"], 0);
    assert_eq!(events[2]["tid"], 0);

    let mut empty = Vec::new();
    write_chrome_trace(&[], &mut empty).expect("write empty");
    let json: serde_json::Value = serde_json::from_slice(&empty).expect("empty trace JSON");
    assert_eq!(json["traceEvents"].as_array().map(Vec::len), Some(0));
}
