// Internals of the Vulkan back end that tests look at.
#pragma once

#include <string>
#include <vector>

namespace gf::demo::detail {

/// Every warning and error the validation layers sent to any Vulkan renderer of this process,
/// including those raised while a renderer was being destroyed (which its own
/// validationMessages() can no longer report).
std::vector<std::string> vulkanValidationLog();

}  // namespace gf::demo::detail
