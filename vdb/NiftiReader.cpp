#include "vdb/Formats.h"
namespace mtcut::vdb {
DenseScan readNifti(const std::string& path, Interrupter*) { throw InputError(path + ": NIfTI reading is not implemented yet"); }
} // namespace mtcut::vdb
