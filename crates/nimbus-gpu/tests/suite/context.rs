//! Context creation and device listing on the validated device.

use nimbus_gpu::{enumerate_devices, vk, Context, ContextDesc};

#[test]
fn lists_devices_and_creates_a_validated_context() {
    let devices = enumerate_devices().expect("enumerate devices");
    assert!(!devices.is_empty());
    for d in &devices {
        eprintln!("{d}");
        assert!(!d.name.is_empty());
        assert!(d.api_version >= vk::API_VERSION_1_1, "{d}");
        assert_eq!(
            d.api_version_string,
            format!(
                "{}.{}.{}",
                vk::api_version_major(d.api_version),
                vk::api_version_minor(d.api_version),
                vk::api_version_patch(d.api_version)
            )
        );
    }

    let ctx = crate::common::validated_context();
    let info = ctx.info();
    eprintln!("{info:#?}");
    assert!(ctx.validation_enabled());
    assert_eq!(devices[info.index].name, info.name);
    assert!(info.compute_queue_family.is_some());
    assert!(info.timestamp_period_ns > 0.0);
    assert!(info.max_push_constants_size >= 128);
    crate::common::assert_no_validation_errors(&ctx);
}

#[test]
fn unknown_device_filter_lists_available_names() {
    let desc = ContextDesc {
        validation: false,
        device_filter: Some("no such device 1234".to_owned()),
        app_name: "nimbus-gpu-tests".to_owned(),
    };
    let err = match Context::new(&desc) {
        Ok(_) => panic!("a context was created for a missing device"),
        Err(e) => format!("{e:#}"),
    };
    assert!(err.contains("no such device 1234"), "{err}");
    let first = &enumerate_devices().expect("enumerate devices")[0].name;
    assert!(err.contains(first.as_str()), "{err}");
}

#[test]
fn validation_messages_are_collected() {
    let ctx = crate::common::validated_context();
    // Provoke one error: a zero-sized storage-buffer range is invalid usage.
    let info = vk::BufferCreateInfo::default()
        .size(0)
        .usage(vk::BufferUsageFlags::STORAGE_BUFFER);
    // SAFETY: a size-0 buffer is deliberately invalid usage, made with the validation layer
    // on so that the layer reports it; `info` outlives the call.
    if let Ok(buffer) = unsafe { ctx.device().create_buffer(&info, None) } {
        // SAFETY: `buffer` was created just above, never bound or used.
        unsafe { ctx.device().destroy_buffer(buffer, None) };
    }
    let errors = ctx.take_validation_errors();
    assert!(
        !errors.is_empty(),
        "the layer reported nothing for a zero-size buffer"
    );
    assert!(
        ctx.validation_errors().is_empty(),
        "take_validation_errors did not drain"
    );
}
