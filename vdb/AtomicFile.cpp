#include "vdb/AtomicFile.h"

#include "vdb/Error.h"

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <unistd.h>

namespace mtcut {

void writeFileAtomically(const std::string& path,
                         const std::function<void(const std::string& tmpPath)>& write)
{
    static std::atomic<unsigned> counter{0};
    const std::string tmp = path + ".tmp." + std::to_string(::getpid()) + "." +
                            std::to_string(counter++);
    try {
        write(tmp);
    } catch (...) {
        std::remove(tmp.c_str());
        throw;
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        const int err = errno;
        std::remove(tmp.c_str());
        throw InputError(path + ": cannot write (" + std::strerror(err) + ")");
    }
}

} // namespace mtcut
