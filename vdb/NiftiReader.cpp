// NIfTI-1 and NIfTI-2 (.nii, .nii.gz, .hdr/.img) through nifti_clib's
// nifti2_io, which reads both versions. The header is read and checked first;
// then only the first 3-D volume is read (a 4-D series gives its first time
// point). World coordinates: sform when sform_code > 0, else qform when
// qform_code > 0, else pixdim along the index axes; NIfTI's RAS is converted
// to LPS. scl_slope/scl_inter are applied (slope 0 means unscaled).
#include "vdb/Formats.h"

#include <nifti2_io.h>

#include <climits>
#include <cmath>
#include <cstdlib>
#include <memory>

namespace mtcut::vdb {

namespace {

struct NiftiDeleter
{
    void operator()(nifti_image* n) const { nifti_image_free(n); }
};

/// Checks the raw header's dim[] before nifti_clib sees it (nifti_clib
/// quietly turns sizes <= 0 into 1 and prints its own complaints).
template <typename Header>
void checkHeaderDims(const Header& h, const std::string& path)
{
    if (h.dim[0] < 1 || h.dim[0] > 7) {
        throw InputError(path + ": NIfTI dim[0] is " + std::to_string(h.dim[0]) + ", must be 1..7");
    }
    for (int d = 1; d <= 3 && d <= h.dim[0]; ++d) {
        if (h.dim[d] <= 0) {
            throw InputError(path + ": NIfTI size along " + std::string(1, "xyz"[d - 1]) + " is " +
                             std::to_string(h.dim[d]) + " voxels, must be positive");
        }
    }
}

template <typename T>
void convert(const void* data, size_t count, double slope, double inter, float* out)
{
    const T* in = static_cast<const T*>(data);
    for (size_t i = 0; i < count; ++i) out[i] = float(double(in[i]) * slope + inter);
}

} // namespace

DenseScan readNifti(const std::string& path, Interrupter* interrupter)
{
    InterrupterScope scope(interrupter, "reading NIfTI");
    pollInterrupter(interrupter, 0);
    nifti_set_debug_level(0); // errors reach the user through InputError, not stderr
    {
        int version = 0;
        std::unique_ptr<void, decltype(&std::free)> hdr(nifti_read_header(path.c_str(), &version, 0), &std::free);
        if (!hdr) throw InputError(path + ": not a readable NIfTI-1/2 file (bad or truncated header)");
        if (version == 2) checkHeaderDims(*static_cast<const nifti_2_header*>(hdr.get()), path);
        else checkHeaderDims(*static_cast<const nifti_1_header*>(hdr.get()), path);
    }
    std::unique_ptr<nifti_image, NiftiDeleter> nim(nifti_image_read(path.c_str(), 0));
    if (!nim) throw InputError(path + ": not a readable NIfTI-1/2 file (bad or truncated header)");

    if (nim->ndim < 2 || nim->ndim > 7) {
        throw InputError(path + ": NIfTI has " + std::to_string(nim->ndim) + " dimensions, expected 3");
    }
    for (int d = 4; d <= 7; ++d) {
        if (d <= nim->ndim && nim->dim[d] <= 0) {
            throw InputError(path + ": NIfTI dim[" + std::to_string(d) + "] is " + std::to_string(nim->dim[d]) +
                             ", must be positive");
        }
    }
    openvdb::Coord dims;
    const int64_t n[3] = {nim->nx, nim->ny, nim->nz};
    for (int a = 0; a < 3; ++a) dims[a] = n[a] > INT32_MAX ? INT32_MAX : n[a] < 0 ? -1 : int(n[a]);
    checkDims(dims, path);

    const int dt = nim->datatype;
    if (dt != DT_INT8 && dt != DT_UINT8 && dt != DT_INT16 && dt != DT_UINT16 && dt != DT_INT32 &&
        dt != DT_UINT32 && dt != DT_FLOAT32 && dt != DT_FLOAT64) {
        throw InputError(path + ": NIfTI datatype " + nifti_datatype_string(dt) +
                         " is not supported (8/16/32-bit integers, float32, float64)");
    }

    DenseScan scan;
    VolumeGeometry& g = scan.geometry;
    g.dims = dims;
    double unit = 1.0; // to mm
    if (nim->xyz_units == NIFTI_UNITS_METER) unit = 1000.0;
    if (nim->xyz_units == NIFTI_UNITS_MICRON) unit = 0.001;
    const nifti_dmat44* m = nim->sform_code > 0 ? &nim->sto_xyz : nim->qform_code > 0 ? &nim->qto_xyz : nullptr;
    const double ras[3] = {-1.0, -1.0, 1.0}; // RAS -> LPS
    if (m) {
        for (int a = 0; a < 3; ++a) {
            openvdb::Vec3d col(m->m[0][a] * ras[0], m->m[1][a] * ras[1], m->m[2][a] * ras[2]);
            col *= unit;
            const double len = col.length();
            if (!std::isfinite(len) || len <= 0.0) {
                throw InputError(path + ": NIfTI " + (nim->sform_code > 0 ? "sform" : "qform") +
                                 " has a zero or invalid column for axis " + std::to_string(a));
            }
            g.spacing[a] = len;
            for (int r = 0; r < 3; ++r) g.direction(r, a) = col[r] / len;
            g.origin[a] = m->m[a][3] * ras[a] * unit;
        }
    } else {
        const double d[3] = {nim->dx, nim->dy, nim->dz};
        for (int a = 0; a < 3; ++a) {
            if (!std::isfinite(d[a]) || d[a] == 0.0) {
                throw InputError(path + ": NIfTI pixdim[" + std::to_string(a + 1) + "] is " + std::to_string(d[a]) +
                                 ", must be a non-zero spacing");
            }
            g.spacing[a] = std::abs(d[a]) * unit;
            g.direction(a, a) = ras[a];
        }
    }

    // Does the file hold the data? (Before nifti_clib allocates it.)
    const uint64_t voxels = uint64_t(dims[0]) * uint64_t(dims[1]) * uint64_t(dims[2]);
    const uint64_t dataBytes = voxels * uint64_t(nim->nbyper);
    if (nim->iname) {
        const int64_t fileBytes = nifti_get_filesize(nim->iname);
        const bool gz = nifti_is_gzfile(nim->iname) != 0;
        const uint64_t offset = nim->iname_offset > 0 ? uint64_t(nim->iname_offset) : 0;
        const uint64_t have = fileBytes > 0 ? uint64_t(fileBytes) : 0;
        if (gz ? have * 1032 + 64 < dataBytes : have < offset + dataBytes) {
            throw InputError(path + ": file has " + std::to_string(have) + (gz ? " compressed" : "") +
                             " bytes, the header describes " + std::to_string(dataBytes) + " bytes of data" +
                             (gz ? "" : " from byte " + std::to_string(offset)) + " (truncated?)");
        }
    }

    // The first 3-D volume only (t = u = v = w = 0).
    const int64_t pick[8] = {0, -1, -1, -1, 0, 0, 0, 0};
    void* raw = nullptr;
    const int64_t bytes = nifti_read_collapsed_image(nim.get(), pick, &raw);
    std::unique_ptr<void, decltype(&std::free)> data(raw, &std::free);
    if (bytes < 0 || !raw || uint64_t(bytes) != dataBytes) {
        throw InputError(path + ": NIfTI data is truncated or unreadable (expected " +
                         std::to_string(dataBytes) + " bytes)");
    }
    pollInterrupter(interrupter, 80);

    double slope = nim->scl_slope, inter = nim->scl_inter;
    if (!std::isfinite(slope) || slope == 0.0) {
        slope = 1.0;
        inter = 0.0;
    }
    if (!std::isfinite(inter)) inter = 0.0;
    scan.values.resize(voxels);
    float* out = scan.values.data();
    switch (dt) {
    case DT_INT8: convert<int8_t>(raw, voxels, slope, inter, out); break;
    case DT_UINT8: convert<uint8_t>(raw, voxels, slope, inter, out); break;
    case DT_INT16: convert<int16_t>(raw, voxels, slope, inter, out); break;
    case DT_UINT16: convert<uint16_t>(raw, voxels, slope, inter, out); break;
    case DT_INT32: convert<int32_t>(raw, voxels, slope, inter, out); break;
    case DT_UINT32: convert<uint32_t>(raw, voxels, slope, inter, out); break;
    case DT_FLOAT32: convert<float>(raw, voxels, slope, inter, out); break;
    case DT_FLOAT64: convert<double>(raw, voxels, slope, inter, out); break;
    }
    pollInterrupter(interrupter, 100);
    return scan;
}

} // namespace mtcut::vdb
