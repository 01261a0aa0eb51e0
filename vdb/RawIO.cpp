#include "vdb/Formats.h"
namespace mtcut::vdb {
DenseScan readRaw(const std::string& path, const RawOptions&, Interrupter*) { throw InputError(path + ": raw is not implemented yet"); }
void writeRaw(const DenseScan&, const std::string& path) { throw InputError(path + ": raw is not implemented yet"); }
} // namespace mtcut::vdb
