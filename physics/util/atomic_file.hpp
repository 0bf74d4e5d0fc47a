// Outputs written whole or not at all: into a temporary file beside the target, then renamed.
#pragma once

#include <string>
#include <string_view>

namespace cutsim {

// Writes `content` to `path` through `path.tmp` and a rename; on any failure the temporary is
// removed, the old file (if any) is left as it was, and InputError names the path.
void writeFileAtomic(const std::string& path, std::string_view content);

}  // namespace cutsim
