//! Instance, device selection, logical device, compute queue and validation messages.
//!
//! The instance asks for Vulkan 1.2. `VK_EXT_debug_utils` is enabled whenever the loader
//! offers it, validation or not, so objects carry names in captures and crash reports.
//! With validation on, `VK_LAYER_KHRONOS_validation` is enabled with synchronization
//! validation (when the layer offers `VK_EXT_validation_features`): lavapipe's single
//! host-visible memory type hides missing staging barriers, the layer does not. Messages
//! of ERROR and WARNING severity are kept in separate lists on the [`Context`] and echoed
//! to stderr; the messenger is also chained into `vkCreateInstance`, so messages from
//! instance creation and destruction are caught too.
//!
//! Device selection: a `device_filter` picks the first device whose name contains it
//! (case-insensitive); otherwise the first discrete GPU, then integrated, virtual, CPU.
//! Either way the device needs a queue family with COMPUTE; among those the one with
//! timestamps and GRAPHICS (the universal queue) is preferred. A device whose compute queue
//! has `timestampValidBits == 0` is still usable; only [`crate::Profiler::new`] refuses it.
//!
//! Thread safety: the allocator, the command pools and the queue sit behind mutexes, so a
//! `&Context` may be shared; the raw handles it hands out carry Vulkan's own rules.

use crate::device::query_devices;
pub use crate::device::{select_device, DeviceInfo};
use crate::error::VkResultExt;
use anyhow::{bail, Context as _, Result};
use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use gpu_allocator::{AllocationSizes, AllocatorDebugSettings};
use std::ffi::{c_void, CStr, CString};
use std::mem::ManuallyDrop;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";
const API_VERSION: u32 = vk::API_VERSION_1_2;

/// How to create a [`Context`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ContextDesc {
    /// Enable `VK_LAYER_KHRONOS_validation` and collect its messages.
    pub validation: bool,
    /// Case-insensitive substring of the device name to pick; `None` picks the best device.
    pub device_filter: Option<String>,
    /// Application name reported to the driver.
    pub app_name: String,
}

impl ContextDesc {
    /// Reads `NIMBUS_VALIDATION=1` (validation on) and `NIMBUS_DEVICE` (device filter).
    pub fn from_env() -> Self {
        let validation = std::env::var("NIMBUS_VALIDATION").is_ok_and(|v| v.trim() == "1");
        let device_filter = std::env::var("NIMBUS_DEVICE")
            .ok()
            .filter(|s| !s.trim().is_empty());
        Self {
            validation,
            device_filter,
            app_name: "nimbus".to_owned(),
        }
    }
}

impl Default for ContextDesc {
    /// Same as [`ContextDesc::from_env`].
    fn default() -> Self {
        Self::from_env()
    }
}

/// Lists every physical device with the information `nimbus devices` prints.
pub fn enumerate_devices() -> Result<Vec<DeviceInfo>> {
    let instance = InstanceBundle::new("nimbus-enumerate", false)?;
    let devices = query_devices(&instance.instance)?;
    Ok(devices.into_iter().map(|(_, info)| info).collect())
}

/// Validation messages collected by the debug messenger.
#[derive(Default)]
struct ValidationSink {
    errors: Mutex<Vec<String>>,
    warnings: Mutex<Vec<String>>,
}

pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user_data: *mut c_void,
) -> vk::Bool32 {
    if data.is_null() || user_data.is_null() {
        return vk::FALSE;
    }
    // SAFETY: the layer passes valid callback data; user_data is the `Arc<ValidationSink>`
    // pointer owned by the `InstanceBundle`, which outlives the messenger and the instance.
    let (data, sink) = unsafe { (&*data, &*(user_data as *const ValidationSink)) };
    let text = |s: Option<&CStr>| s.map(|s| s.to_string_lossy().into_owned());
    // SAFETY: `data` is the layer's callback data for this call (checked non-null above),
    // whose `pMessageIdName` is null or a NUL-terminated string valid for the callback.
    let id = unsafe { text(data.message_id_name_as_c_str()) }.unwrap_or_default();
    // SAFETY: as above: `pMessage` of the layer's callback data is a NUL-terminated string
    // valid for the callback.
    let message = unsafe { text(data.message_as_c_str()) }.unwrap_or_default();
    let line = format!("{id}: {message}");
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        eprintln!("[nimbus-gpu] validation error: {line}");
        lock(&sink.errors).push(line);
    } else if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING) {
        eprintln!("[nimbus-gpu] validation warning: {line}");
        lock(&sink.warnings).push(line);
    }
    vk::FALSE
}

/// Loader, instance and messenger; destroys the messenger and instance when dropped.
struct InstanceBundle {
    _entry: ash::Entry,
    instance: ash::Instance,
    debug_utils: Option<ash::ext::debug_utils::Instance>,
    messenger: vk::DebugUtilsMessengerEXT,
    sink: Arc<ValidationSink>,
}

impl InstanceBundle {
    fn new(app_name: &str, validation: bool) -> Result<Self> {
        // SAFETY: loading libvulkan runs its initialisers; nothing else is loaded here.
        let entry = unsafe { ash::Entry::load() }.context(
            "loading the Vulkan loader (libvulkan.so.1); install libvulkan1 and a driver, \
             e.g. mesa-vulkan-drivers for lavapipe",
        )?;
        let has_extension = |list: &[vk::ExtensionProperties], name: &CStr| {
            list.iter()
                .any(|e| e.extension_name_as_c_str().is_ok_and(|n| n == name))
        };
        // SAFETY: `entry` holds a loaded Vulkan loader; the call takes no pointers of ours.
        let loader_extensions = unsafe { entry.enumerate_instance_extension_properties(None) }
            .vk_context(|| "vkEnumerateInstanceExtensionProperties")?;
        let mut layer_extensions = Vec::new();
        if validation {
            // SAFETY: `entry` holds a loaded Vulkan loader; the call takes no pointers of
            // ours.
            let layers = unsafe { entry.enumerate_instance_layer_properties() }
                .vk_context(|| "vkEnumerateInstanceLayerProperties")?;
            let found = layers
                .iter()
                .any(|l| l.layer_name_as_c_str().is_ok_and(|n| n == VALIDATION_LAYER));
            if !found {
                bail!(
                    "validation was requested but the layer VK_LAYER_KHRONOS_validation is not \
                     installed; install the `vulkan-validationlayers` package (Debian/Ubuntu) \
                     or turn validation off (unset NIMBUS_VALIDATION)"
                );
            }
            // SAFETY: `entry` holds a loaded loader and `VALIDATION_LAYER` is a NUL-
            // terminated name of a layer found just above.
            layer_extensions =
                unsafe { entry.enumerate_instance_extension_properties(Some(VALIDATION_LAYER)) }
                    .vk_context(|| {
                        "vkEnumerateInstanceExtensionProperties for the validation layer"
                    })?;
        }
        let debug_utils_name = ash::ext::debug_utils::NAME;
        let has_debug_utils = has_extension(&loader_extensions, debug_utils_name)
            || has_extension(&layer_extensions, debug_utils_name);
        if validation && !has_debug_utils {
            bail!("validation was requested but VK_EXT_debug_utils is not available");
        }
        let has_validation_features =
            validation && has_extension(&layer_extensions, ash::ext::validation_features::NAME);

        let mut extensions = Vec::new();
        if has_debug_utils {
            extensions.push(debug_utils_name.as_ptr());
        }
        if has_validation_features {
            extensions.push(ash::ext::validation_features::NAME.as_ptr());
        }
        let layers = if validation {
            vec![VALIDATION_LAYER.as_ptr()]
        } else {
            Vec::new()
        };

        let app_name_c = CString::new(app_name.replace('\0', " "))
            .context("application name contains a NUL byte")?;
        let app_info = vk::ApplicationInfo::default()
            .application_name(&app_name_c)
            .application_version(0)
            .engine_name(c"nimbus")
            .engine_version(0)
            .api_version(API_VERSION);

        let sink = Arc::new(ValidationSink::default());
        let mut messenger_info = vk::DebugUtilsMessengerCreateInfoEXT::default()
            .message_severity(
                vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
                    | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
            )
            .message_type(
                vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                    | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                    | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
            )
            .pfn_user_callback(Some(debug_callback))
            .user_data(Arc::as_ptr(&sink) as *mut c_void);
        let enabled_features = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
        let mut validation_features =
            vk::ValidationFeaturesEXT::default().enabled_validation_features(&enabled_features);

        let mut create_info = vk::InstanceCreateInfo::default()
            .application_info(&app_info)
            .enabled_layer_names(&layers)
            .enabled_extension_names(&extensions);
        if validation {
            create_info = create_info.push_next(&mut messenger_info);
        }
        if has_validation_features {
            create_info = create_info.push_next(&mut validation_features);
        }
        // SAFETY: `create_info` and everything it points to (the application info and its
        // name, the layer and extension name arrays, and the chained messenger and
        // validation-features structs) are locals that outlive the call; every layer and
        // extension named was found in the lists above.
        let instance = unsafe { entry.create_instance(&create_info, None) }.vk_context(|| {
            format!(
                "vkCreateInstance (Vulkan 1.2, validation {})",
                if validation { "on" } else { "off" }
            )
        })?;

        let mut bundle = Self {
            debug_utils: has_debug_utils
                .then(|| ash::ext::debug_utils::Instance::new(&entry, &instance)),
            _entry: entry,
            instance,
            messenger: vk::DebugUtilsMessengerEXT::null(),
            sink,
        };
        if let (true, Some(debug_utils)) = (validation, &bundle.debug_utils) {
            // SAFETY: `debug_utils` was loaded for this instance, which is alive;
            // `messenger_info` points at `debug_callback` and at `sink`, which this bundle
            // owns and keeps until after the messenger is destroyed.
            bundle.messenger =
                unsafe { debug_utils.create_debug_utils_messenger(&messenger_info, None) }
                    .vk_context(|| "vkCreateDebugUtilsMessengerEXT")?;
        }
        Ok(bundle)
    }
}

impl Drop for InstanceBundle {
    fn drop(&mut self) {
        // SAFETY: the messenger and instance were created here and nothing else owns them;
        // the device (if any) was destroyed by `Context::drop` before this runs.
        unsafe {
            if let Some(debug_utils) = &self.debug_utils {
                if self.messenger != vk::DebugUtilsMessengerEXT::null() {
                    debug_utils.destroy_debug_utils_messenger(self.messenger, None);
                }
            }
            self.instance.destroy_instance(None);
        }
    }
}

/// The device, its compute queue, the memory allocator and the validation message lists.
pub struct Context {
    device: ash::Device,
    physical_device: vk::PhysicalDevice,
    queue: Mutex<vk::Queue>,
    queue_family_index: u32,
    allocator: ManuallyDrop<Mutex<Allocator>>,
    pub(crate) command_pools: Mutex<Vec<vk::CommandPool>>,
    debug_utils: Option<ash::ext::debug_utils::Device>,
    info: DeviceInfo,
    validation: bool,
    /// Pipelines built so far, handed out again for the same description.
    pub(crate) pipelines: Mutex<crate::pipeline_cache::PipelineCache>,
    /// Compute dispatches recorded so far (work counters: dispatches per frame).
    pub(crate) dispatches: std::sync::atomic::AtomicU64,
    /// Declared last: dropped (messenger, instance) after `Drop::drop` destroyed the device.
    instance: InstanceBundle,
}

impl Context {
    /// Compute dispatches recorded with this context so far.
    pub fn dispatch_count(&self) -> u64 {
        self.dispatches.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Creates the instance, picks a device (see the module docs) and creates the device,
    /// its compute queue and the allocator.
    pub fn new(desc: &ContextDesc) -> Result<Context> {
        let instance = InstanceBundle::new(&desc.app_name, desc.validation)?;
        let devices = query_devices(&instance.instance)?;
        let infos: Vec<DeviceInfo> = devices.iter().map(|(_, i)| i.clone()).collect();
        let index = select_device(&infos, desc.device_filter.as_deref())?;
        let (physical_device, info) = devices[index].clone();
        let queue_family_index = info
            .compute_queue_family
            .with_context(|| format!("device '{}' has no compute queue family", info.name))?;

        let priorities = [1.0f32];
        let queue_infos = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(queue_family_index)
            .queue_priorities(&priorities)];
        let device_info = vk::DeviceCreateInfo::default().queue_create_infos(&queue_infos);
        // SAFETY: `physical_device` was enumerated from this live instance, and
        // `device_info` and the queue infos and priorities it points to outlive the call;
        // the queue family has COMPUTE and one queue is asked for.
        let device = unsafe {
            instance
                .instance
                .create_device(physical_device, &device_info, None)
        }
        .vk_context(|| format!("vkCreateDevice for '{}'", info.name))?;

        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.instance.clone(),
            device: device.clone(),
            physical_device,
            debug_settings: AllocatorDebugSettings::default(),
            buffer_device_address: false,
            allocation_sizes: AllocationSizes::default(),
        });
        let allocator = match allocator {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: nothing was created on the device yet.
                unsafe { device.destroy_device(None) };
                return Err(e).with_context(|| {
                    format!("creating the gpu-allocator allocator for '{}'", info.name)
                });
            }
        };
        // SAFETY: the device was created with one queue of `queue_family_index`, so queue 0
        // of that family exists.
        let queue = unsafe { device.get_device_queue(queue_family_index, 0) };
        let debug_utils = instance
            .debug_utils
            .as_ref()
            .map(|_| ash::ext::debug_utils::Device::new(&instance.instance, &device));

        let ctx = Context {
            device,
            physical_device,
            queue: Mutex::new(queue),
            queue_family_index,
            allocator: ManuallyDrop::new(Mutex::new(allocator)),
            command_pools: Mutex::new(Vec::new()),
            debug_utils,
            info,
            validation: desc.validation,
            pipelines: Mutex::default(),
            dispatches: std::sync::atomic::AtomicU64::new(0),
            instance,
        };
        ctx.set_name(
            ctx.device.handle(),
            &format!("nimbus device '{}'", ctx.info.name),
        );
        ctx.set_name(queue, "nimbus compute queue");
        Ok(ctx)
    }

    pub fn info(&self) -> &DeviceInfo {
        &self.info
    }

    /// Raw device, for recording passes.
    pub fn device(&self) -> &ash::Device {
        &self.device
    }

    pub fn instance(&self) -> &ash::Instance {
        &self.instance.instance
    }

    pub fn physical_device(&self) -> vk::PhysicalDevice {
        self.physical_device
    }

    pub fn queue_family_index(&self) -> u32 {
        self.queue_family_index
    }

    /// Locks the compute queue for a raw submission; [`Context::submit_one_shot`] takes the
    /// same lock, so holding it across a one-shot deadlocks.
    pub fn lock_queue(&self) -> MutexGuard<'_, vk::Queue> {
        lock(&self.queue)
    }

    /// Whether the validation layer is on.
    pub fn validation_enabled(&self) -> bool {
        self.validation
    }

    pub(crate) fn allocator(&self) -> MutexGuard<'_, Allocator> {
        lock(&self.allocator)
    }

    /// Every ERROR-severity validation message seen so far.
    pub fn validation_errors(&self) -> Vec<String> {
        lock(&self.instance.sink.errors).clone()
    }

    /// Returns and clears the ERROR-severity validation messages.
    pub fn take_validation_errors(&self) -> Vec<String> {
        std::mem::take(&mut *lock(&self.instance.sink.errors))
    }

    /// Every WARNING-severity validation message seen so far.
    pub fn validation_warnings(&self) -> Vec<String> {
        lock(&self.instance.sink.warnings).clone()
    }

    /// Returns and clears the WARNING-severity validation messages.
    pub fn take_validation_warnings(&self) -> Vec<String> {
        std::mem::take(&mut *lock(&self.instance.sink.warnings))
    }

    /// Gives `handle` a debug-utils name; a no-op without `VK_EXT_debug_utils`.
    pub fn set_name<H: vk::Handle>(&self, handle: H, name: &str) {
        let Some(debug_utils) = &self.debug_utils else {
            return;
        };
        let Ok(name) = CString::new(name.replace('\0', " ")) else {
            return;
        };
        let info = vk::DebugUtilsObjectNameInfoEXT::default()
            .object_handle(handle)
            .object_name(&name);
        // Naming is diagnostics only: a failure must not fail the caller.
        // SAFETY: `handle` is a live object of this device (every caller names an object it
        // just created or owns) and `info` and `name` outlive the call.
        let _ = unsafe { debug_utils.set_debug_utils_object_name(&info) };
    }

    /// Opens a debug-utils label region in `cmd` (shown by RenderDoc / Nsight); a no-op
    /// without `VK_EXT_debug_utils`.
    pub fn cmd_begin_label(&self, cmd: vk::CommandBuffer, label: &str) {
        let Some(debug_utils) = &self.debug_utils else {
            return;
        };
        let Ok(label) = CString::new(label.replace('\0', " ")) else {
            return;
        };
        let info = vk::DebugUtilsLabelEXT::default().label_name(&label);
        // SAFETY: the caller's `cmd` is a recording command buffer of this device; `info`
        // and `label` outlive the call.
        unsafe { debug_utils.cmd_begin_debug_utils_label(cmd, &info) };
    }

    /// Closes the label region opened by [`Context::cmd_begin_label`].
    pub fn cmd_end_label(&self, cmd: vk::CommandBuffer) {
        if let Some(debug_utils) = &self.debug_utils {
            // SAFETY: the caller's `cmd` is a recording command buffer of this device with
            // a label region opened by `cmd_begin_label`.
            unsafe { debug_utils.cmd_end_debug_utils_label(cmd) };
        }
    }

    /// Waits until the device is idle.
    pub fn wait_idle(&self) -> Result<()> {
        let _queue = self.lock_queue();
        // SAFETY: the queue mutex is held above, as vkDeviceWaitIdle needs every queue of
        // the device externally synchronized.
        unsafe { self.device.device_wait_idle() }
            .vk_context(|| format!("vkDeviceWaitIdle on '{}'", self.info.name))
    }
}

impl Drop for Context {
    fn drop(&mut self) {
        // SAFETY: `&mut self` means no other user; teardown runs in reverse creation order:
        // allocator memory, command pools, device; the instance follows in field drop.
        unsafe {
            if let Err(e) = self.device.device_wait_idle() {
                eprintln!(
                    "[nimbus-gpu] vkDeviceWaitIdle failed during teardown: {}",
                    crate::VkError(e)
                );
            }
            let pipelines = lock(&self.pipelines).drain();
            for built in pipelines {
                self.destroy_built(built);
            }
            ManuallyDrop::drop(&mut self.allocator);
            let pools = std::mem::take(&mut *lock(&self.command_pools));
            for pool in pools {
                self.device.destroy_command_pool(pool, None);
            }
            self.device.destroy_device(None);
        }
    }
}
