//! Physical devices: what each is ([`DeviceInfo`], read from the driver by
//! `query_devices`) and which one a [`crate::Context`] takes ([`select_device`], the
//! rule in the `context` module docs).

use anyhow::{bail, Context as _, Result};
use ash::vk;
use std::fmt;

use crate::error::VkResultExt;

/// What a physical device is and what the compute work here needs to know about it.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceInfo {
    /// Position in `vkEnumeratePhysicalDevices` order.
    pub index: usize,
    pub name: String,
    pub device_type: vk::PhysicalDeviceType,
    /// Packed `VK_MAKE_API_VERSION` value.
    pub api_version: u32,
    /// `api_version` as `major.minor.patch`.
    pub api_version_string: String,
    /// `VkPhysicalDeviceDriverProperties::driverName`; empty before Vulkan 1.2.
    pub driver_name: String,
    /// `VkPhysicalDeviceDriverProperties::driverInfo`; empty before Vulkan 1.2.
    pub driver_info: String,
    /// The queue family a [`crate::Context`] on this device would use; `None` if none has
    /// COMPUTE.
    pub compute_queue_family: Option<u32>,
    /// Nanoseconds per timestamp tick (`timestampPeriod`).
    pub timestamp_period_ns: f32,
    /// `timestampValidBits` of the compute queue family; 0 means no timestamps.
    pub timestamp_valid_bits: u32,
    /// Default subgroup size; 0 before Vulkan 1.1.
    pub subgroup_size: u32,
    pub max_storage_buffer_range: u32,
    pub max_uniform_buffer_range: u32,
    pub max_push_constants_size: u32,
    pub max_compute_work_group_count: [u32; 3],
    pub max_compute_work_group_size: [u32; 3],
    pub max_compute_work_group_invocations: u32,
    pub max_image_dimension_2d: u32,
    pub max_image_dimension_3d: u32,
    /// `maxMemoryAllocationSize` (Vulkan 1.1); 0 when the device does not report it.
    pub max_memory_allocation_size: u64,
    /// Size of the largest device-local memory heap in bytes.
    pub device_local_bytes: u64,
}

impl DeviceInfo {
    /// The most loop iterations one shader invocation may run, where the device limits
    /// them: llvmpipe (lavapipe) silently ends every loop of an invocation once 65535
    /// iterations have run in it (`LP_MAX_TGSI_LOOP_ITERATIONS`, shared by all its
    /// loops). `None` where there is no such limit.
    pub fn loop_budget(&self) -> Option<u32> {
        let llvmpipe = self.driver_name.contains("llvmpipe") || self.name.contains("llvmpipe");
        llvmpipe.then_some(65_535)
    }

    /// Human name of the device type ("discrete GPU", "CPU", ...).
    pub fn device_type_name(&self) -> &'static str {
        match self.device_type {
            vk::PhysicalDeviceType::DISCRETE_GPU => "discrete GPU",
            vk::PhysicalDeviceType::INTEGRATED_GPU => "integrated GPU",
            vk::PhysicalDeviceType::VIRTUAL_GPU => "virtual GPU",
            vk::PhysicalDeviceType::CPU => "CPU",
            _ => "other",
        }
    }
}

impl fmt::Display for DeviceInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "[{}] {} ({}), Vulkan {}, driver {} {}",
            self.index,
            self.name,
            self.device_type_name(),
            self.api_version_string,
            self.driver_name,
            self.driver_info
        )?;
        if self.timestamp_valid_bits == 0 {
            write!(f, ", no timestamps")?;
        }
        Ok(())
    }
}

/// Picks the device index per the `context` module docs; pure, so selection is testable without a GPU.
pub fn select_device(devices: &[DeviceInfo], filter: Option<&str>) -> Result<usize> {
    let names = || {
        devices
            .iter()
            .map(|d| format!("'{}'", d.name))
            .collect::<Vec<_>>()
            .join(", ")
    };
    if devices.is_empty() {
        bail!("no Vulkan devices found (install a driver, e.g. mesa-vulkan-drivers for lavapipe)");
    }
    if let Some(filter) = filter {
        let needle = filter.to_lowercase();
        let Some(pos) = devices
            .iter()
            .position(|d| d.name.to_lowercase().contains(&needle))
        else {
            bail!(
                "no Vulkan device name contains '{filter}'; available: {}",
                names()
            );
        };
        if devices[pos].compute_queue_family.is_none() {
            bail!(
                "device '{}' matches '{filter}' but has no compute queue family",
                devices[pos].name
            );
        }
        return Ok(pos);
    }
    let rank = |t: vk::PhysicalDeviceType| match t {
        vk::PhysicalDeviceType::DISCRETE_GPU => 0,
        vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
        vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
        vk::PhysicalDeviceType::CPU => 3,
        _ => 4,
    };
    devices
        .iter()
        .enumerate()
        .filter(|(_, d)| d.compute_queue_family.is_some())
        .min_by_key(|(i, d)| (rank(d.device_type), *i))
        .map(|(i, _)| i)
        .with_context(|| {
            format!(
                "no Vulkan device has a compute queue; available: {}",
                names()
            )
        })
}

fn c_chars_to_string(chars: &[std::ffi::c_char]) -> String {
    let bytes: Vec<u8> = chars
        .iter()
        .take_while(|&&c| c != 0)
        .map(|&c| c as u8)
        .collect();
    String::from_utf8_lossy(&bytes).into_owned()
}

pub(crate) fn query_devices(
    instance: &ash::Instance,
) -> Result<Vec<(vk::PhysicalDevice, DeviceInfo)>> {
    // SAFETY: `instance` is a live instance borrowed for the call.
    let physical_devices = unsafe { instance.enumerate_physical_devices() }
        .vk_context(|| "vkEnumeratePhysicalDevices")?;
    Ok(physical_devices
        .into_iter()
        .enumerate()
        .map(|(index, pd)| (pd, query_device_info(instance, pd, index)))
        .collect())
}

fn query_device_info(instance: &ash::Instance, pd: vk::PhysicalDevice, index: usize) -> DeviceInfo {
    // SAFETY: `pd` was enumerated from `instance`, which is alive.
    let props = unsafe { instance.get_physical_device_properties(pd) };
    let api = props.api_version;
    let mut driver = vk::PhysicalDeviceDriverProperties::default();
    let mut subgroup = vk::PhysicalDeviceSubgroupProperties::default();
    let mut maintenance3 = vk::PhysicalDeviceMaintenance3Properties::default();
    // Ask for 1.1 / 1.2 properties only from devices that define them.
    if api >= vk::API_VERSION_1_1 {
        let mut props2 = vk::PhysicalDeviceProperties2::default()
            .push_next(&mut subgroup)
            .push_next(&mut maintenance3);
        if api >= vk::API_VERSION_1_2 {
            props2 = props2.push_next(&mut driver);
        }
        // SAFETY: `pd` was enumerated from `instance`; the chained output structs are
        // locals that outlive the call, and each is chained only when the device's API
        // version defines it (checked above).
        unsafe { instance.get_physical_device_properties2(pd, &mut props2) };
    }
    // SAFETY: `pd` was enumerated from `instance`, which is alive.
    let families = unsafe { instance.get_physical_device_queue_family_properties(pd) };
    let compute_queue_family = families
        .iter()
        .enumerate()
        .filter(|(_, f)| f.queue_flags.contains(vk::QueueFlags::COMPUTE) && f.queue_count > 0)
        .min_by_key(|(i, f)| {
            (
                f.timestamp_valid_bits == 0,
                !f.queue_flags.contains(vk::QueueFlags::GRAPHICS),
                *i,
            )
        })
        .map(|(i, _)| i as u32);
    let timestamp_valid_bits = compute_queue_family
        .map(|i| families[i as usize].timestamp_valid_bits)
        .unwrap_or(0);
    let limits = &props.limits;
    // SAFETY: `pd` was enumerated from `instance`, which is alive.
    let memory = unsafe { instance.get_physical_device_memory_properties(pd) };
    let device_local_bytes = memory.memory_heaps[..memory.memory_heap_count as usize]
        .iter()
        .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
        .map(|h| h.size)
        .max()
        .unwrap_or(0);
    DeviceInfo {
        index,
        name: c_chars_to_string(&props.device_name),
        device_type: props.device_type,
        api_version: api,
        api_version_string: format!(
            "{}.{}.{}",
            vk::api_version_major(api),
            vk::api_version_minor(api),
            vk::api_version_patch(api)
        ),
        driver_name: c_chars_to_string(&driver.driver_name),
        driver_info: c_chars_to_string(&driver.driver_info),
        compute_queue_family,
        timestamp_period_ns: limits.timestamp_period,
        timestamp_valid_bits,
        subgroup_size: subgroup.subgroup_size,
        max_storage_buffer_range: limits.max_storage_buffer_range,
        max_uniform_buffer_range: limits.max_uniform_buffer_range,
        max_push_constants_size: limits.max_push_constants_size,
        max_compute_work_group_count: limits.max_compute_work_group_count,
        max_compute_work_group_size: limits.max_compute_work_group_size,
        max_compute_work_group_invocations: limits.max_compute_work_group_invocations,
        max_image_dimension_2d: limits.max_image_dimension2_d,
        max_image_dimension_3d: limits.max_image_dimension3_d,
        // Vulkan 1.1 guarantees at least 1 GiB; 0 (pre-1.1) means unknown.
        max_memory_allocation_size: maintenance3.max_memory_allocation_size,
        device_local_bytes,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info(index: usize, name: &str, device_type: vk::PhysicalDeviceType) -> DeviceInfo {
        DeviceInfo {
            index,
            name: name.to_owned(),
            device_type,
            api_version: vk::API_VERSION_1_3,
            api_version_string: "1.3.0".to_owned(),
            driver_name: String::new(),
            driver_info: String::new(),
            compute_queue_family: Some(0),
            timestamp_period_ns: 1.0,
            timestamp_valid_bits: 64,
            subgroup_size: 32,
            max_storage_buffer_range: 1 << 27,
            max_uniform_buffer_range: 1 << 16,
            max_push_constants_size: 128,
            max_compute_work_group_count: [65535; 3],
            max_compute_work_group_size: [1024, 1024, 64],
            max_compute_work_group_invocations: 1024,
            max_image_dimension_2d: 16384,
            max_image_dimension_3d: 2048,
            max_memory_allocation_size: 1 << 30,
            device_local_bytes: 8 << 30,
        }
    }

    #[test]
    fn selection_prefers_discrete_then_integrated_then_cpu() {
        let devices = vec![
            info(0, "llvmpipe", vk::PhysicalDeviceType::CPU),
            info(1, "Intel UHD", vk::PhysicalDeviceType::INTEGRATED_GPU),
            info(2, "NVIDIA RTX", vk::PhysicalDeviceType::DISCRETE_GPU),
        ];
        assert_eq!(select_device(&devices, None).unwrap(), 2);
        assert_eq!(select_device(&devices[..2], None).unwrap(), 1);
        assert_eq!(select_device(&devices[..1], None).unwrap(), 0);
    }

    #[test]
    fn selection_skips_devices_without_compute() {
        let mut devices = vec![
            info(0, "NVIDIA RTX", vk::PhysicalDeviceType::DISCRETE_GPU),
            info(1, "llvmpipe", vk::PhysicalDeviceType::CPU),
        ];
        devices[0].compute_queue_family = None;
        assert_eq!(select_device(&devices, None).unwrap(), 1);
        let err = select_device(&devices, Some("rtx")).unwrap_err();
        assert!(format!("{err:#}").contains("no compute queue"), "{err:#}");
    }

    #[test]
    fn filter_is_case_insensitive_and_lists_names_on_miss() {
        let devices = vec![
            info(0, "NVIDIA RTX", vk::PhysicalDeviceType::DISCRETE_GPU),
            info(
                1,
                "llvmpipe (LLVM 15.0.6, 256 bits)",
                vk::PhysicalDeviceType::CPU,
            ),
        ];
        assert_eq!(select_device(&devices, Some("LLVMPIPE")).unwrap(), 1);
        let err = format!("{:#}", select_device(&devices, Some("radeon")).unwrap_err());
        assert!(
            err.contains("'NVIDIA RTX'") && err.contains("'llvmpipe"),
            "{err}"
        );
        assert!(select_device(&[], None).is_err());
    }
}
