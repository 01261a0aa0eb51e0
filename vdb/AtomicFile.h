// Writing output files so that a failure never leaves half a file behind.
#pragma once

#include <functional>
#include <string>

namespace mtcut {

/// Calls write(tmpPath) with a temporary name in the same folder as path,
/// then renames it to path. If write throws, the temporary file is removed
/// and the exception propagates: path is then untouched. A format with a
/// companion file (a detached NRRD header's data) writes each file with its
/// own call, data first.
void writeFileAtomically(const std::string& path,
                         const std::function<void(const std::string& tmpPath)>& write);

} // namespace mtcut
