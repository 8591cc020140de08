//! GPU timestamp profiler: nested scopes, a result tree, per-pass statistics and a Chrome
//! trace, in the shape of wgpu-profiler but without a global instance.
//!
//! A frame is `begin_frame` (resets the query pool in the command buffer), any number of
//! nested `begin_scope` / `end_scope` pairs, the submission and its fence wait, then
//! `resolve`. Each scope takes two queries, both reserved when it opens, so a frame holds
//! at most `max_scopes` scopes; one more is an error, never a silent drop. Timestamps are
//! written at BOTTOM_OF_PIPE: each waits for every earlier command, so a child scope lies
//! inside its parent and scopes separated by [`crate::compute_barrier`] measure their own
//! dispatches. Ticks are masked to the queue's `timestampValidBits` (wrap-around safe) and
//! scaled by `timestampPeriod`; results are relative to the frame's first timestamp.

use crate::context::Context;
use crate::error::VkResultExt;
use anyhow::{bail, Result};
use ash::vk;
use std::io::Write;

/// Timestamp scopes of one frame at a time, recorded into caller-provided command buffers.
pub struct Profiler {
    device: ash::Device,
    pool: vk::QueryPool,
    name: String,
    capacity: u32,
    next_query: u32,
    open: Vec<usize>,
    scopes: Vec<PendingScope>,
    frame_open: bool,
    timestamp_period_ns: f32,
    valid_bits: u32,
}

struct PendingScope {
    label: String,
    begin_query: u32,
    end_query: u32,
    parent: Option<usize>,
}

/// One resolved scope; times in nanoseconds from the frame's first timestamp.
#[derive(Clone, Debug, PartialEq)]
pub struct ScopeResult {
    pub label: String,
    pub begin_ns: f64,
    pub end_ns: f64,
    pub children: Vec<ScopeResult>,
}

impl ScopeResult {
    pub fn duration_ns(&self) -> f64 {
        self.end_ns - self.begin_ns
    }

    pub fn duration_ms(&self) -> f64 {
        self.duration_ns() * 1e-6
    }
}

/// Statistics of one scope path (`"frame/initial"`) over several frames, in milliseconds.
#[derive(Clone, Debug, PartialEq)]
pub struct PassStats {
    pub label: String,
    pub median_ms: f64,
    pub min_ms: f64,
    pub max_ms: f64,
    pub mean_ms: f64,
    pub samples: usize,
}

/// Nanoseconds between two raw timestamps of a queue with `valid_bits` valid bits.
///
/// Both ticks are masked to the valid bits and the difference is taken modulo 2^valid_bits,
/// so a counter that wrapped between `begin` and `end` still gives the elapsed time.
pub fn ticks_to_ns(begin: u64, end: u64, valid_bits: u32, period_ns: f32) -> f64 {
    let mask = if valid_bits >= 64 {
        u64::MAX
    } else {
        (1u64 << valid_bits) - 1
    };
    let ticks = (end & mask).wrapping_sub(begin & mask) & mask;
    ticks as f64 * f64::from(period_ns)
}

impl Profiler {
    /// Creates a timestamp query pool for `max_scopes` scopes per frame.
    pub fn new(ctx: &Context, max_scopes: u32, name: &str) -> Result<Profiler> {
        let info = ctx.info();
        if info.timestamp_valid_bits == 0 {
            bail!(
                "profiler '{name}': the compute queue of '{}' has timestampValidBits = 0, \
                 so GPU timestamps are unsupported and passes cannot be timed",
                info.name
            );
        }
        let Some(capacity) = max_scopes.checked_mul(2).filter(|&c| c > 0) else {
            bail!(
                "profiler '{name}': max_scopes must be between 1 and {}",
                u32::MAX / 2
            );
        };
        let pool_info = vk::QueryPoolCreateInfo::default()
            .query_type(vk::QueryType::TIMESTAMP)
            .query_count(capacity);
        // SAFETY: `pool_info` asks for `capacity` (> 0, checked above) timestamp queries
        // and outlives the call; the pool is destroyed by `Profiler::destroy`.
        let pool =
            unsafe { ctx.device().create_query_pool(&pool_info, None) }.vk_context(|| {
                format!("vkCreateQueryPool for profiler '{name}' ({capacity} queries)")
            })?;
        ctx.set_name(pool, &format!("{name} (timestamps)"));
        Ok(Profiler {
            device: ctx.device().clone(),
            pool,
            name: name.to_owned(),
            capacity,
            next_query: 0,
            open: Vec::new(),
            scopes: Vec::new(),
            frame_open: false,
            timestamp_period_ns: info.timestamp_period_ns,
            valid_bits: info.timestamp_valid_bits,
        })
    }

    /// Number of queries in the pool (two per scope).
    pub fn capacity(&self) -> u32 {
        self.capacity
    }

    /// Starts a frame: resets the query pool in `cmd` and forgets the previous frame.
    pub fn begin_frame(&mut self, cmd: vk::CommandBuffer) {
        // SAFETY: `self.pool` is alive until `destroy` consumes the profiler, and the range
        // `0..capacity` is the whole pool; the caller's `cmd` is recording, outside any
        // render pass (this crate records compute only).
        unsafe {
            self.device
                .cmd_reset_query_pool(cmd, self.pool, 0, self.capacity)
        };
        self.scopes.clear();
        self.open.clear();
        self.next_query = 0;
        self.frame_open = true;
    }

    /// Opens a scope (nested inside the innermost open one) and writes its begin timestamp.
    pub fn begin_scope(
        &mut self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        label: &str,
    ) -> Result<()> {
        if !self.frame_open {
            bail!(
                "profiler '{}': begin_scope('{label}') outside a frame; call begin_frame first",
                self.name
            );
        }
        if self.next_query + 2 > self.capacity {
            bail!(
                "profiler query pool overflow (capacity {}): scope '{label}' does not fit in \
                 profiler '{}' ({} scopes per frame)",
                self.capacity,
                self.name,
                self.capacity / 2
            );
        }
        let begin_query = self.next_query;
        self.next_query += 2;
        // SAFETY: `begin_query + 1 < capacity` was checked above, and the pool was reset in
        // this frame's `begin_frame` (`frame_open` checked); `self.pool` is alive and the
        // caller's `cmd` is recording.
        unsafe {
            ctx.device().cmd_write_timestamp(
                cmd,
                vk::PipelineStageFlags::BOTTOM_OF_PIPE,
                self.pool,
                begin_query,
            )
        };
        ctx.cmd_begin_label(cmd, label);
        self.scopes.push(PendingScope {
            label: label.to_owned(),
            begin_query,
            end_query: begin_query + 1,
            parent: self.open.last().copied(),
        });
        self.open.push(self.scopes.len() - 1);
        Ok(())
    }

    /// Closes the innermost open scope and writes its end timestamp.
    pub fn end_scope(&mut self, ctx: &Context, cmd: vk::CommandBuffer) -> Result<()> {
        let Some(index) = self.open.pop() else {
            bail!("profiler '{}': end_scope without an open scope", self.name);
        };
        ctx.cmd_end_label(cmd);
        // SAFETY: `end_query` was reserved inside the pool by `begin_scope` (which checked
        // the capacity), and the pool was reset in this frame; `self.pool` is alive and the
        // caller's `cmd` is recording.
        unsafe {
            ctx.device().cmd_write_timestamp(
                cmd,
                vk::PipelineStageFlags::BOTTOM_OF_PIPE,
                self.pool,
                self.scopes[index].end_query,
            )
        };
        Ok(())
    }

    /// Reads the frame's timestamps and builds the scope tree. Call it after waiting on the
    /// fence of the submission that recorded the scopes; it ends the frame.
    pub fn resolve(&mut self, ctx: &Context) -> Result<Vec<ScopeResult>> {
        if !self.open.is_empty() {
            let labels: Vec<&str> = self
                .open
                .iter()
                .map(|&i| self.scopes[i].label.as_str())
                .collect();
            bail!(
                "profiler '{}': cannot resolve with open scopes {labels:?}",
                self.name
            );
        }
        self.frame_open = false;
        if self.scopes.is_empty() {
            return Ok(Vec::new());
        }
        let mut ticks = vec![0u64; self.next_query as usize];
        // Read without WAIT: unsubmitted scopes must be an error, not a hang.
        // SAFETY: `ticks` holds `next_query` u64 slots for queries `0..next_query` of the
        // live pool, read as TYPE_64 without WAIT, so a query not yet written gives
        // NOT_READY instead of a hang.
        let read = unsafe {
            ctx.device().get_query_pool_results(
                self.pool,
                0,
                &mut ticks,
                vk::QueryResultFlags::TYPE_64,
            )
        };
        match read {
            Ok(()) => {}
            Err(vk::Result::NOT_READY) => bail!(
                "profiler '{}': timestamps not ready; resolve after the fence wait of the \
                 submission that recorded the scopes",
                self.name
            ),
            Err(e) => {
                return Err(e)
                    .vk_context(|| format!("vkGetQueryPoolResults for profiler '{}'", self.name))
            }
        }
        let origin = ticks[self.scopes[0].begin_query as usize];
        let to_ns = |query: u32| {
            ticks_to_ns(
                origin,
                ticks[query as usize],
                self.valid_bits,
                self.timestamp_period_ns,
            )
        };
        let mut children: Vec<Vec<usize>> = vec![Vec::new(); self.scopes.len()];
        let mut roots = Vec::new();
        for (i, scope) in self.scopes.iter().enumerate() {
            match scope.parent {
                Some(p) => children[p].push(i),
                None => roots.push(i),
            }
        }
        fn build(
            i: usize,
            scopes: &[PendingScope],
            children: &[Vec<usize>],
            to_ns: &dyn Fn(u32) -> f64,
        ) -> ScopeResult {
            let scope = &scopes[i];
            ScopeResult {
                label: scope.label.clone(),
                begin_ns: to_ns(scope.begin_query),
                end_ns: to_ns(scope.end_query),
                children: children[i]
                    .iter()
                    .map(|&c| build(c, scopes, children, to_ns))
                    .collect(),
            }
        }
        Ok(roots
            .into_iter()
            .map(|i| build(i, &self.scopes, &children, &to_ns))
            .collect())
    }

    /// Destroys the query pool. The GPU must be done with it.
    pub fn destroy(self, ctx: &Context) {
        // SAFETY: the profiler is consumed, so the pool is no longer reachable, and by this
        // function's contract the GPU is done with every command buffer that wrote it.
        unsafe { ctx.device().destroy_query_pool(self.pool, None) };
    }
}

/// Per-path statistics over `frames`, in the order paths were first seen (parents first).
pub fn summarize(frames: &[Vec<ScopeResult>]) -> Vec<PassStats> {
    let mut order: Vec<String> = Vec::new();
    let mut samples: std::collections::HashMap<String, Vec<f64>> = Default::default();
    for frame in frames {
        let mut flat = Vec::new();
        preorder(frame, "", &mut flat);
        for (path, scope) in flat {
            if !samples.contains_key(&path) {
                order.push(path.clone());
            }
            samples.entry(path).or_default().push(scope.duration_ms());
        }
    }
    order
        .into_iter()
        .filter_map(|label| {
            let mut ms = samples.remove(&label)?;
            ms.sort_by(f64::total_cmp);
            let n = ms.len();
            let median_ms = if n % 2 == 1 {
                ms[n / 2]
            } else {
                0.5 * (ms[n / 2 - 1] + ms[n / 2])
            };
            Some(PassStats {
                label,
                median_ms,
                min_ms: ms[0],
                max_ms: ms[n - 1],
                mean_ms: ms.iter().sum::<f64>() / n as f64,
                samples: n,
            })
        })
        .collect()
}

/// Lists scopes parent-first with their `/`-joined label paths.
fn preorder<'a>(scopes: &'a [ScopeResult], prefix: &str, out: &mut Vec<(String, &'a ScopeResult)>) {
    for scope in scopes {
        let path = if prefix.is_empty() {
            scope.label.clone()
        } else {
            format!("{prefix}/{}", scope.label)
        };
        out.push((path.clone(), scope));
        preorder(&scope.children, &path, out);
    }
}

fn write_json_string(out: &mut impl Write, s: &str) -> std::io::Result<()> {
    out.write_all(b"\"")?;
    for c in s.chars() {
        match c {
            '"' => out.write_all(b"\\\"")?,
            '\\' => out.write_all(b"\\\\")?,
            '\n' => out.write_all(b"\\n")?,
            '\r' => out.write_all(b"\\r")?,
            '\t' => out.write_all(b"\\t")?,
            c if (c as u32) < 0x20 => write!(out, "\\u{:04x}", c as u32)?,
            c => write!(out, "{c}")?,
        }
    }
    out.write_all(b"\"")
}

/// Writes `frames` as a Chrome trace (`chrome://tracing`, Perfetto): one complete ("X")
/// event per scope in microseconds, each frame placed after the previous frame's end.
pub fn write_chrome_trace(
    frames: &[Vec<ScopeResult>],
    out: &mut impl Write,
) -> std::io::Result<()> {
    out.write_all(b"{\"traceEvents\":[")?;
    let mut first = true;
    let mut offset_ns = 0.0;
    for (frame_index, frame) in frames.iter().enumerate() {
        let mut events = Vec::new();
        preorder(frame, "", &mut events);
        for (_, scope) in events {
            if !first {
                out.write_all(b",")?;
            }
            first = false;
            out.write_all(b"\n{\"name\":")?;
            write_json_string(out, &scope.label)?;
            write!(
                out,
                ",\"cat\":\"gpu\",\"ph\":\"X\",\"ts\":{:.3},\"dur\":{:.3},\"pid\":0,\"tid\":0,\
                 \"args\":{{\"frame\":{frame_index}}}}}",
                (offset_ns + scope.begin_ns) * 1e-3,
                scope.duration_ns().max(0.0) * 1e-3
            )?;
        }
        offset_ns += frame.iter().map(|s| s.end_ns).fold(0.0, f64::max);
    }
    out.write_all(b"\n],\"displayTimeUnit\":\"ms\"}\n")
}
