#include "vdb/HeaderParsers.h"

#include "vdb/Error.h"

namespace mtcut::vdb {

RawOptions parseRawOptions(std::string_view) { throw InputError("raw options are not implemented yet"); }
MetaImageHeader parseMetaImageHeader(std::string_view, const std::string& source) { throw InputError(source + ": MetaImage is not implemented yet"); }

} // namespace mtcut::vdb
