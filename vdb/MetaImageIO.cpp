#include "vdb/Formats.h"
namespace mtcut::vdb {
DenseScan readMetaImage(const std::string& path, Interrupter*) { throw InputError(path + ": MetaImage is not implemented yet"); }
void writeMetaImage(const DenseScan&, const std::string& path) { throw InputError(path + ": MetaImage is not implemented yet"); }
} // namespace mtcut::vdb
