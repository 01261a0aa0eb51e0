#include "vdb/Formats.h"
namespace mtcut::vdb {
DenseScan readDicomSeries(const std::string& folder, const ReadOptions&, Interrupter*)
{
    throw InputError(folder + ": DICOM reading is not implemented yet");
}
} // namespace mtcut::vdb
