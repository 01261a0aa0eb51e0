#include "vdb/Formats.h"
namespace mtcut::vdb {
DenseScan readNrrd(const std::string& path, Interrupter*) { throw InputError(path + ": NRRD reading is not implemented yet"); }
void writeNrrd(const DenseScan&, const std::string& path) { throw InputError(path + ": NRRD writing is not implemented yet"); }
} // namespace mtcut::vdb
