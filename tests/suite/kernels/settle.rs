//! The settling load of timed renders (`nimbus::renderer::settle`): it runs, under
//! validation, for the time asked and no less; it grows its dispatches; it is skipped on
//! a CPU device, where it would only cost time.

use std::time::Duration;

use nimbus::renderer::settle::{applies, settle, Settled};

use crate::common::gpu::{assert_no_validation_errors, context};

#[test]
fn settling_keeps_the_device_busy_for_the_time_asked() {
    let ctx = context();
    assert_eq!(settle(&ctx, Duration::ZERO).unwrap(), Settled::default());
    let asked = Duration::from_millis(60);
    let settled = settle(&ctx, asked).unwrap();
    assert!(settled.elapsed >= asked, "{settled:?}");
    assert!(settled.dispatches >= 1, "{settled:?}");
    // The first dispatch is 16 workgroups; each that takes under 4 ms doubles the next.
    assert!(settled.groups >= 16, "{settled:?}");
    assert!(
        settled.elapsed < asked + Duration::from_secs(5),
        "one dispatch must stay short: {settled:?}"
    );
    assert_no_validation_errors(&ctx);
    // Lavapipe has no clocks to raise: timed renders skip the load there.
    let cpu = ctx.info().device_type == nimbus_gpu::vk::PhysicalDeviceType::CPU;
    assert_eq!(applies(&ctx), !cpu);
}
