// libFuzzer target: a path file (cutter/PATH_FORMAT.md) read, filtered into
// quads and voxelised, and, when bit 1 of the first byte is set, raw poses
// (8 doubles each, any finite magnitude) straight into the path filter, which
// must refuse what lies beyond kMaxPoseMm, and the voxeliser, which must clip
// what lies outside the frame and never convert an out-of-range bound to int
// (UBSan found one at 2e52 mm, and NaN from a 1.8e307 mm blade). Bit 0: kerf 0.5 mm.
#include "cutter/BladePath.h"
#include "cutter/PathFile.h"
#include "vdb/Error.h"
#include <cmath>
#include <cstring>
#include <sstream>
#include <string>
using namespace mtcut;
static void voxelize(const std::vector<cutter::Pose>& s, double kerf)
{
    cutter::IndexFrame frame;
    frame.dims = glm::ivec3(48, 40, 32);
    frame.spacing = glm::dvec3(1.0, 1.0, 2.0);
    std::vector<cutter::Quad> quads;
    try {
        quads = cutter::filterStroke(s, frame);
    } catch (const InputError&) {
        return;
    }
    std::vector<glm::ivec3> cells;
    for (const cutter::Quad& q : quads) {
        cells.clear();
        cutter::voxelizeCut(q, kerf, frame, cells);
        if (cells.size() > 100000) __builtin_trap();
        for (const glm::ivec3& c : cells)
            if (c.x < -1 || c.y < -1 || c.z < -1 || c.x > 47 || c.y > 39 || c.z > 31) __builtin_trap();
    }
}
extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    if (size < 1) return 0;
    const double kerf = (data[0] & 1) ? 0.5 : 0.0;
    if (data[0] & 2) { // raw poses: 8 doubles each, finite ones only, any magnitude
        std::vector<cutter::Pose> poses;
        for (size_t o = 1; o + 64 <= size; o += 64) {
            double v[8];
            std::memcpy(v, data + o, 64);
            bool ok = true;
            for (double x : v) ok = ok && std::isfinite(x);
            if (!ok) continue;
            cutter::Pose p;
            p.time = poses.empty() ? 0.0 : poses.back().time + 1e-3;
            p.base = glm::dvec3(v[1], v[2], v[3]);
            p.direction = glm::dvec3(v[4], v[5], v[6]);
            p.length = v[7];
            poses.push_back(p);
        }
        voxelize(poses, kerf);
        return 0;
    }
    std::istringstream in(std::string(reinterpret_cast<const char*>(data + 1), size - 1));
    std::vector<std::vector<cutter::Pose>> strokes;
    try {
        strokes = cutter::readPath(in, "fuzz");
    } catch (const InputError&) {
        return 0;
    }
    for (const auto& s : strokes) voxelize(s, kerf);
    return 0;
}
