//! 3D image round trip and a 2D storage image written by a shader that samples a 3D image.

use nimbus_gpu::{vk, BindingDesc, ComputePipelineDesc, DescriptorWrite, ImageDesc, SamplerDesc};

#[test]
fn volume_image_round_trips() {
    let ctx = crate::common::validated_context();
    let desc = ImageDesc::sampled_3d(8, 4, 2, vk::Format::R32_SFLOAT);
    let image = ctx.create_image(&desc, "volume 8x4x2").expect("image");
    let texels: Vec<f32> = (0..8 * 4 * 2).map(|i| i as f32 * 0.5 - 3.0).collect();
    ctx.upload_image(&image, bytemuck::cast_slice(&texels))
        .expect("upload");
    let back = ctx.readback_image(&image).expect("readback");
    assert_eq!(bytemuck::cast_slice::<u8, f32>(&back), &texels[..]);

    let err = ctx.upload_image(&image, &[0; 12]).unwrap_err();
    assert!(
        format!("{err:#}").contains("needs 256 bytes, got 12"),
        "{err:#}"
    );

    ctx.destroy_image(image);
    crate::common::assert_no_validation_errors(&ctx);
}

const SHADER: &str = r#"
#version 450
layout(local_size_x = 8, local_size_y = 8) in;
layout(set = 0, binding = 0, rgba32f) uniform writeonly image2D target;
layout(set = 0, binding = 1) uniform sampler3D volume;
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(target);
    if (p.x >= size.x || p.y >= size.y) {
        return;
    }
    float v = texelFetch(volume, ivec3(p.x % 8, p.y % 4, 1), 0).r;
    imageStore(target, p, vec4(float(p.x), float(p.y), v, 1.0));
}
"#;

#[test]
fn storage_image_written_by_a_shader() {
    let ctx = crate::common::validated_context();
    let (width, height) = (20u32, 12u32);
    let target = ctx
        .create_image(
            &ImageDesc::storage_2d(width, height, vk::Format::R32G32B32A32_SFLOAT),
            "target rgba32f",
        )
        .expect("target image");
    let volume = ctx
        .create_image(
            &ImageDesc::sampled_3d(8, 4, 2, vk::Format::R32_SFLOAT),
            "volume",
        )
        .expect("volume image");
    let texels: Vec<f32> = (0..64).map(|i| i as f32).collect();
    ctx.upload_image(&volume, bytemuck::cast_slice(&texels))
        .expect("upload volume");
    let sampler = ctx
        .create_sampler(&SamplerDesc::nearest(), "nearest")
        .expect("sampler");

    let spirv = crate::common::compile_compute(SHADER, "storage_image.comp");
    let bindings = [BindingDesc::storage_image(0), BindingDesc::sampled_image(1)];
    let pipeline = ctx
        .create_compute_pipeline(
            &ComputePipelineDesc {
                spirv: &spirv,
                entry: "main",
                bindings: &bindings,
                push_constant_size: 0,
                specialization: &[],
            },
            "storage image",
        )
        .expect("pipeline");
    let set = ctx
        .create_descriptor_set(
            &pipeline,
            &[
                DescriptorWrite::StorageImage {
                    binding: 0,
                    image: &target,
                },
                DescriptorWrite::SampledImage {
                    binding: 1,
                    image: &volume,
                    sampler,
                },
            ],
            "storage image set",
        )
        .expect("set");
    ctx.submit_one_shot("write storage image", |cmd| {
        pipeline.dispatch(
            &ctx,
            cmd,
            &set,
            &[],
            [width.div_ceil(8), height.div_ceil(8), 1],
        )
    })
    .expect("dispatch");

    let bytes = ctx.readback_image(&target).expect("readback");
    let pixels: &[[f32; 4]] = bytemuck::cast_slice(&bytes);
    assert_eq!(pixels.len(), (width * height) as usize);
    for y in 0..height {
        for x in 0..width {
            let volume_index = 32 + (y % 4) * 8 + x % 8;
            let expected = [x as f32, y as f32, volume_index as f32, 1.0];
            assert_eq!(
                pixels[(y * width + x) as usize],
                expected,
                "pixel ({x}, {y})"
            );
        }
    }

    ctx.destroy_descriptor_set(set);
    ctx.destroy_compute_pipeline(pipeline);
    ctx.destroy_sampler(sampler);
    ctx.destroy_image(target);
    ctx.destroy_image(volume);
    crate::common::assert_no_validation_errors(&ctx);
}

#[test]
fn unsupported_image_requests_are_errors() {
    let ctx = crate::common::validated_context();
    let mut desc = ImageDesc::storage_2d(4, 4, vk::Format::R32_SFLOAT);
    desc.extent.depth = 2;
    let err = ctx.create_image(&desc, "deep 2d").unwrap_err();
    assert!(format!("{err:#}").contains("'deep 2d'"), "{err:#}");
    crate::common::assert_no_validation_errors(&ctx);
}
