//! Upload and readback round trips through staging and mapped buffers.

use nimbus_gpu::{vk, BufferDesc};

const MIB: usize = 1 << 20;

#[test]
fn gpu_only_buffer_round_trips_through_staging() {
    let ctx = crate::common::validated_context();
    let data = crate::common::pattern(MIB, 0x5eed);
    let buffer = ctx
        .create_buffer(
            &BufferDesc::gpu_only(MIB as u64, vk::BufferUsageFlags::STORAGE_BUFFER),
            "round trip",
        )
        .expect("create buffer");
    assert!(
        buffer.mapped_slice().is_none(),
        "GpuOnly buffers must not expose a mapping"
    );
    ctx.upload_buffer(&buffer, 0, &data).expect("upload");
    let back = ctx.readback_buffer(&buffer).expect("readback");
    assert!(back == data, "1 MiB round trip differs");

    // Overwrite a window at an offset and read a range around it.
    let patch = crate::common::pattern(4096, 7);
    ctx.upload_buffer(&buffer, 12_288, &patch)
        .expect("upload at offset");
    let window = ctx
        .readback_buffer_range(&buffer, 8192, 12_288)
        .expect("readback range");
    assert_eq!(&window[..4096], &data[8192..12_288]);
    assert_eq!(&window[4096..8192], &patch[..]);
    assert_eq!(&window[8192..], &data[16_384..20_480]);

    let err = ctx
        .upload_buffer(&buffer, MIB as u64 - 2, &[0; 4])
        .unwrap_err();
    assert!(
        format!("{err:#}").contains("overflows buffer 'round trip'"),
        "{err:#}"
    );

    ctx.fill_buffer(&buffer, 0xdead_beef).expect("fill");
    let filled = ctx
        .readback_buffer_range(&buffer, 0, 16)
        .expect("readback fill");
    assert_eq!(filled, 0xdead_beef_u32.to_ne_bytes().repeat(4));

    ctx.destroy_buffer(buffer);
    crate::common::assert_no_validation_errors(&ctx);
}

#[test]
fn mapped_buffers_round_trip_without_staging() {
    let ctx = crate::common::validated_context();
    let data = crate::common::pattern(64 * 1024, 42);
    let upload = ctx
        .create_buffer(
            &BufferDesc::host_to_gpu(data.len() as u64, vk::BufferUsageFlags::STORAGE_BUFFER),
            "mapped upload",
        )
        .expect("create upload buffer");
    let readback = ctx
        .create_buffer(
            &BufferDesc::gpu_to_host(data.len() as u64, vk::BufferUsageFlags::STORAGE_BUFFER),
            "mapped readback",
        )
        .expect("create readback buffer");
    assert!(upload.is_mapped() && readback.is_mapped());
    ctx.upload_buffer(&upload, 0, &data).expect("mapped upload");
    assert_eq!(upload.mapped_slice().expect("mapping"), &data[..]);

    // Copy on the GPU, then read through the mapping.
    ctx.submit_one_shot("copy mapped", |cmd| {
        let region = vk::BufferCopy {
            src_offset: 0,
            dst_offset: 0,
            size: data.len() as u64,
        };
        // SAFETY: `cmd` is this one-shot's buffer, recording; both buffers are alive for
        // the test and `data.len()` bytes fit in each (both were made that size), and
        // `upload` / `readback` have TRANSFER_SRC / TRANSFER_DST usage.
        unsafe {
            ctx.device()
                .cmd_copy_buffer(cmd, upload.raw, readback.raw, &[region])
        };
        Ok(())
    })
    .expect("copy");
    assert!(ctx.readback_buffer(&readback).expect("mapped readback") == data);

    ctx.destroy_buffer(upload);
    ctx.destroy_buffer(readback);
    crate::common::assert_no_validation_errors(&ctx);
}

#[test]
fn zero_sized_buffer_is_an_error() {
    let ctx = crate::common::validated_context();
    let err = ctx
        .create_buffer(
            &BufferDesc::gpu_only(0, vk::BufferUsageFlags::STORAGE_BUFFER),
            "empty",
        )
        .unwrap_err();
    assert!(format!("{err:#}").contains("'empty'"), "{err:#}");
    crate::common::assert_no_validation_errors(&ctx);
}
