// The code a specialized compute shader can reach, and nothing else: SPIRV-Tools'
// optimizer with the passes that turn specialization constants into constants and
// remove what they make unreachable (see crates/nimbus-gpu/src/spirv_strip.rs).
//
// The C API of Debian 12's SPIRV-Tools (2023.1) has no optimizer entry point, so this
// one function wraps spvtools::Optimizer for Rust.

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

#include <spirv-tools/optimizer.hpp>

namespace {

// Copies `text` into `out` (capacity `cap`, NUL-terminated, truncated if needed).
void copy_message(const std::string& text, char* out, size_t cap) {
    if (out == nullptr || cap == 0) {
        return;
    }
    size_t n = text.size() < cap - 1 ? text.size() : cap - 1;
    std::memcpy(out, text.data(), n);
    out[n] = '\0';
}

}  // namespace

// Runs the passes on `words[0..count)` (a SPIR-V module for Vulkan 1.2). On success
// returns 0 and sets `*out` to a malloc'd array of `*out_count` words, which the caller
// frees with nimbus_spirv_free. On failure returns nonzero, sets nothing, and writes
// the optimizer's messages to `message` (capacity `message_cap`).
extern "C" int nimbus_spirv_strip(const uint32_t* words, size_t count, uint32_t** out,
                                  size_t* out_count, char* message, size_t message_cap) {
    try {
        spvtools::Optimizer optimizer(SPV_ENV_VULKAN_1_2);
        std::string messages;
        optimizer.SetMessageConsumer([&messages](spv_message_level_t level, const char*,
                                                 const spv_position_t& position,
                                                 const char* text) {
            if (level <= SPV_MSG_ERROR) {
                messages += "word " + std::to_string(position.index) + ": " + text + "\n";
            }
        });
        optimizer.RegisterPass(spvtools::CreateFreezeSpecConstantValuePass())
            .RegisterPass(spvtools::CreateFoldSpecConstantOpAndCompositePass())
            .RegisterPass(spvtools::CreateDeadBranchElimPass())
            .RegisterPass(spvtools::CreateAggressiveDCEPass())
            .RegisterPass(spvtools::CreateBlockMergePass())
            .RegisterPass(spvtools::CreateEliminateDeadFunctionsPass());
        spvtools::OptimizerOptions options;
        // The validation layer validates what is handed to the driver; the input was
        // produced by shaderc from the same sources.
        options.set_run_validator(false);
        std::vector<uint32_t> result;
        if (!optimizer.Run(words, count, &result, options)) {
            copy_message(messages.empty() ? std::string("the optimizer failed") : messages,
                         message, message_cap);
            return 1;
        }
        uint32_t* copy = static_cast<uint32_t*>(std::malloc(result.size() * sizeof(uint32_t)));
        if (copy == nullptr) {
            copy_message("out of memory", message, message_cap);
            return 2;
        }
        std::memcpy(copy, result.data(), result.size() * sizeof(uint32_t));
        *out = copy;
        *out_count = result.size();
        return 0;
    } catch (const std::exception& e) {
        copy_message(std::string("exception: ") + e.what(), message, message_cap);
        return 3;
    } catch (...) {
        copy_message("unknown exception", message, message_cap);
        return 3;
    }
}

extern "C" void nimbus_spirv_free(uint32_t* words) { std::free(words); }
