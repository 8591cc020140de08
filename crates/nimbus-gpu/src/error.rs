//! Vulkan result codes as error values.
//!
//! ash's `Display` for `vk::Result` prints only the specification's description ("A device
//! memory allocation has failed"); [`VkError`] prints the code name as well, so an error
//! chain reads `vkCreateBuffer for 'reservoirs': ERROR_OUT_OF_DEVICE_MEMORY (A device memory
//! allocation has failed)`. Every `VK_ERROR_*` is reported the same way: nothing in this
//! crate retries or recovers, except `VK_TIMEOUT` from the one-shot fence wait, which
//! becomes a "GPU timeout" error.

use ash::vk;
use std::fmt;

/// A failed Vulkan call's result code; the source of every Vulkan error from this crate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VkError(pub vk::Result);

impl fmt::Display for VkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:?} ({})", self.0, self.0)
    }
}

impl std::error::Error for VkError {}

/// Attaches context to a `Result<T, vk::Result>`, keeping the code name in the message.
pub(crate) trait VkResultExt<T> {
    fn vk_context<C, F>(self, context: F) -> anyhow::Result<T>
    where
        C: fmt::Display + Send + Sync + 'static,
        F: FnOnce() -> C;
}

impl<T> VkResultExt<T> for Result<T, vk::Result> {
    fn vk_context<C, F>(self, context: F) -> anyhow::Result<T>
    where
        C: fmt::Display + Send + Sync + 'static,
        F: FnOnce() -> C,
    {
        self.map_err(|result| vk_error(result, context()))
    }
}

/// Wraps a failed result code with context.
pub(crate) fn vk_error<C>(result: vk::Result, context: C) -> anyhow::Error
where
    C: fmt::Display + Send + Sync + 'static,
{
    anyhow::Error::new(VkError(result)).context(context)
}
