// The procedural CT-head phantom: determinism, anatomy at known world points,
// any grid size, sparsity and the connected pieces of bone.
#include "TestUtil.h"

#include "vdb/Phantom.h"

#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

using namespace mtcut;
using namespace mtcut::vdb;
using openvdb::Coord;
using openvdb::Vec3d;

namespace {

uint64_t hashValues(const std::vector<float>& values)
{
    uint64_t h = 1469598103934665603ULL; // FNV-1a over the bytes
    const auto* bytes = reinterpret_cast<const unsigned char*>(values.data());
    for (size_t i = 0; i < values.size() * sizeof(float); ++i) h = (h ^ bytes[i]) * 1099511628211ULL;
    return h;
}

PhantomOptions options(Coord dims, uint32_t seed = 1, float noiseSigma = 15.0f)
{
    PhantomOptions o;
    o.dims = dims;
    o.seed = seed;
    o.noiseSigma = noiseSigma;
    return o;
}

/// Value of the voxel whose centre is nearest to a world point (mm).
float valueAt(const Volume& vol, const Vec3d& world)
{
    const Coord ijk = vol.grid->transform().worldToIndexCellCentered(world);
    EXPECT_TRUE(vol.indexBox().isInside(ijk)) << world;
    return vol.grid->tree().getValue(ijk);
}

/// Dense scan lookup by index or by world point (nearest voxel centre).
struct DenseView
{
    const DenseScan& scan;
    size_t offset(const Coord& c) const
    {
        const Coord& d = scan.geometry.dims;
        return (size_t(c.z()) * d.y() + c.y()) * d.x() + c.x();
    }
    Coord ijkOf(const Vec3d& world) const
    {
        const auto& g = scan.geometry;
        Coord c;
        for (int a = 0; a < 3; ++a) c[a] = int(std::lround((world[a] - g.origin[a]) / g.spacing[a]));
        return c;
    }
    float at(const Vec3d& world) const { return scan.values[offset(ijkOf(world))]; }
};

/// Connected components (6-neighbourhood) of {value >= iso}; label per voxel, 0 = not bone.
struct Components
{
    std::vector<int> label;
    int count = 0;
};

Components bonePieces(const DenseScan& scan, float iso)
{
    const Coord d = scan.geometry.dims;
    const size_t n = scan.values.size();
    Components c;
    c.label.assign(n, 0);
    std::vector<size_t> stack;
    for (size_t first = 0; first < n; ++first) {
        if (scan.values[first] < iso || c.label[first] != 0) continue;
        const int id = ++c.count;
        c.label[first] = id;
        stack.push_back(first);
        while (!stack.empty()) {
            const size_t v = stack.back();
            stack.pop_back();
            const int i = int(v % d.x()), j = int((v / d.x()) % d.y()), k = int(v / (size_t(d.x()) * d.y()));
            const int nb[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
            for (const auto& o : nb) {
                const int x = i + o[0], y = j + o[1], z = k + o[2];
                if (x < 0 || y < 0 || z < 0 || x >= d.x() || y >= d.y() || z >= d.z()) continue;
                const size_t w = (size_t(z) * d.y() + y) * d.x() + x;
                if (scan.values[w] >= iso && c.label[w] == 0) {
                    c.label[w] = id;
                    stack.push_back(w);
                }
            }
        }
    }
    return c;
}

class RecordingInterrupter : public Interrupter
{
public:
    explicit RecordingInterrupter(int cancelAfter = -1) : mCancelAfter(cancelAfter) {}
    void start(const char* name) override
    {
        std::lock_guard<std::mutex> lock(mMutex);
        names.push_back(name ? name : "");
    }
    bool wasInterrupted(int percent) override
    {
        std::lock_guard<std::mutex> lock(mMutex);
        percents.push_back(percent);
        return mCancelAfter >= 0 && int(percents.size()) > mCancelAfter;
    }
    std::vector<std::string> names;
    std::vector<int> percents;

private:
    int mCancelAfter;
    std::mutex mMutex;
};

} // namespace

TEST(Phantom, FieldOfViewFixedAtAnyGridSize)
{
    const Vec3d fov = phantomFieldOfView();
    EXPECT_EQ(fov, Vec3d(240.0, 240.0, 256.0));
    for (const Coord dims : {Coord(9, 7, 5), Coord(37, 41, 29), Coord(20, 60, 10), Coord(1, 1, 1)}) {
        const Volume vol = makePhantom(options(dims));
        EXPECT_EQ(vol.dims, dims);
        EXPECT_EQ(vol.units, "HU");
        EXPECT_EQ(vol.source, "phantom");
        const Vec3d s = vol.spacing(), o = vol.origin();
        for (int a = 0; a < 3; ++a) {
            EXPECT_NEAR(s[a] * dims[a], fov[a], 1e-9) << dims;
            EXPECT_NEAR(o[a], -0.5 * fov[a] + 0.5 * s[a], 1e-9) << dims;
        }
        // Noise is bounded by 2 sqrt(3) sigma = 52 HU around air (-1000) and enamel (2700).
        EXPECT_GE(vol.minValue, -1000.0f - 52.0f) << dims;
        EXPECT_LE(vol.maxValue, 2700.0f + 52.0f) << dims;
    }
    // A coarse grid still holds the head: bone in it, air around it.
    const Volume coarse = makePhantom(options(Coord(37, 41, 29)));
    EXPECT_GT(coarse.maxValue, 1000.0f);
    EXPECT_LT(valueAt(coarse, phantomLandmarks().outsideHead), -900.0f);
}

TEST(Phantom, RejectsBadOptions)
{
    EXPECT_THROW(makePhantomScan(options(Coord(0, 8, 8))), InputError);
    EXPECT_THROW(makePhantomScan(options(Coord(8, 8, -1))), InputError);
    EXPECT_THROW(makePhantomScan(options(Coord(8, 8, 8), 1, -1.0f)), InputError);
    EXPECT_THROW(makePhantomScan(options(Coord(8, 8, 8), 1, std::nanf(""))), InputError);
}

TEST(Phantom, DeterministicFromSeedWhateverTheThreads)
{
    const Coord dims(64, 72, 48);
    const DenseScan a = makePhantomScan(options(dims, 1));
    const DenseScan b = makePhantomScan(options(dims, 1));
    ASSERT_EQ(a.values.size(), size_t(64) * 72 * 48);
    EXPECT_EQ(hashValues(a.values), hashValues(b.values));

    const DenseScan other = makePhantomScan(options(dims, 2));
    size_t differ = 0;
    for (size_t i = 0; i < a.values.size(); ++i) differ += a.values[i] != other.values[i];
    EXPECT_GT(differ, a.values.size() * 99 / 100); // the noise differs nearly everywhere

    uint64_t oneThread = 0;
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
        oneThread = hashValues(makePhantomScan(options(dims, 1)).values);
    }
    EXPECT_EQ(oneThread, hashValues(a.values));

    // The noise-free phantom does not depend on the seed.
    EXPECT_EQ(hashValues(makePhantomScan(options(dims, 1, 0.0f)).values),
              hashValues(makePhantomScan(options(dims, 7, 0.0f)).values));
}

TEST(Phantom, NoiseIsBoundedWithTheRequestedSigma)
{
    const Coord dims(64, 64, 64);
    const DenseScan clean = makePhantomScan(options(dims, 3, 0.0f));
    const DenseScan noisy = makePhantomScan(options(dims, 3, 15.0f));
    double sum = 0.0, sum2 = 0.0, maxAbs = 0.0;
    for (size_t i = 0; i < clean.values.size(); ++i) {
        const double n = double(noisy.values[i]) - double(clean.values[i]);
        sum += n;
        sum2 += n * n;
        maxAbs = std::max(maxAbs, std::abs(n));
    }
    const double count = double(clean.values.size());
    const double mean = sum / count, sd = std::sqrt(sum2 / count - mean * mean);
    EXPECT_NEAR(mean, 0.0, 0.1); // standard error 15 / 512 = 0.03
    EXPECT_NEAR(sd, 15.0, 0.15); // 1 %
    EXPECT_LE(maxAbs, 2.0 * std::sqrt(3.0) * 15.0 + 1e-3);
    EXPECT_GT(maxAbs, 40.0); // the tails are reached (P(|n| > 40) per voxel is about 1e-3)
}

TEST(Phantom, AnatomyAtKnownPoints)
{
    const PhantomLandmarks l = phantomLandmarks();
    // 0.94 x 0.94 x 2 mm voxels, noise-free: tissue values are exact away from boundaries.
    const Volume clean = makePhantom(options(Coord(256, 256, 128), 1, 0.0f));
    EXPECT_EQ(valueAt(clean, l.outsideHead), -1000.0f);
    EXPECT_EQ(valueAt(clean, l.maxillarySinus), -1000.0f);
    EXPECT_EQ(valueAt(clean, l.brain), 32.0f);
    EXPECT_EQ(valueAt(clean, l.vertebraBody), 480.0f);
    EXPECT_EQ(valueAt(clean, l.mandibleBone), 480.0f);
    EXPECT_EQ(valueAt(clean, l.upperIncisorCrown), 2700.0f);
    EXPECT_EQ(valueAt(clean, l.upperMolarCrown), 2700.0f);
    EXPECT_EQ(valueAt(clean, l.lowerIncisorCrown), 2700.0f);
    EXPECT_EQ(valueAt(clean, l.skullLateral), 1600.0f);
    EXPECT_GT(valueAt(clean, l.maxillaBone), 400.0f);

    // With noise (seed 1, sigma 15, bounded by 52 HU): the thresholds a user relies on.
    const Volume vol = makePhantom(options(Coord(256, 256, 128), 1));
    EXPECT_LT(valueAt(vol, l.outsideHead), -900.0f);
    EXPECT_LT(valueAt(vol, l.maxillarySinus), -900.0f);
    const float brain = valueAt(vol, l.brain);
    EXPECT_GE(brain, 0.0f);
    EXPECT_LE(brain, 60.0f);
    EXPECT_GT(valueAt(vol, l.skullLateral), 1000.0f);
    EXPECT_GT(valueAt(vol, l.vertexBone), 1000.0f);
    EXPECT_GT(valueAt(vol, l.upperIncisorCrown), 2000.0f);
    EXPECT_GT(valueAt(vol, l.lowerIncisorCrown), 2000.0f);
    EXPECT_GT(valueAt(vol, l.vertebraBody), 300.0f);
    EXPECT_GT(valueAt(vol, l.mandibleBone), 300.0f);

    // Orientation: the face (teeth) is anterior (-y) of the brain, the vertex at +z.
    EXPECT_LT(l.upperIncisorCrown.y(), l.brain.y() - 80.0);
    EXPECT_LT(l.upperMolarCrown.y(), l.brain.y() - 40.0);
    EXPECT_GT(l.brain.z(), l.upperIncisorCrown.z() + 100.0);
    EXPECT_GT(l.upperCrownBottomZ, l.lowerCrownTopZ);
    // The LeFort I plane runs through the sinuses, above the upper roots (tips at z = -28 + 3.2).
    EXPECT_GT(l.leFortZ, -24.0);
    EXPECT_EQ(valueAt(clean, Vec3d(l.maxillarySinus.x(), l.maxillarySinus.y(), l.leFortZ)), -1000.0f);

    // Where the enamel (>= 2000 HU) is, and where the highest bone is.
    double teethY = 0.0, teethZ = 0.0;
    uint64_t teeth = 0;
    double topBoneZ = -1e9;
    for (auto it = vol.grid->cbeginValueOn(); it; ++it) {
        const Vec3d w = vol.grid->indexToWorld(it.getCoord());
        if (*it >= 2000.0f) {
            teethY += w.y();
            teethZ += w.z();
            ++teeth;
        }
        if (*it >= 400.0f) topBoneZ = std::max(topBoneZ, w.z());
    }
    ASSERT_GT(teeth, 1000u);
    EXPECT_LT(teethY / double(teeth), l.brain.y() - 60.0);
    EXPECT_LT(teethZ / double(teeth), -40.0);
    // The top of the skull is the highest bone: none above it, some within a voxel below it.
    EXPECT_LE(topBoneZ, l.skullTopZ + 1.0);
    EXPECT_GE(topBoneZ, l.skullTopZ - 2.0);
    EXPECT_LT(valueAt(vol, Vec3d(0.0, 5.0, l.skullTopZ + 2.0 * vol.spacing().z())), 400.0f);
}

TEST(Phantom, SameHeadAtAnotherResolution)
{
    // Noise-free: the landmarks hold the same tissue at 1.9 mm and 0.47 mm voxels.
    const PhantomLandmarks l = phantomLandmarks();
    const DenseScan coarse = makePhantomScan(options(Coord(128, 128, 128), 1, 0.0f));
    const DenseScan fine = makePhantomScan(options(Coord(512, 512, 64), 1, 0.0f));
    for (const DenseScan* s : {&coarse, &fine}) {
        const DenseView v{*s};
        EXPECT_EQ(v.at(l.brain), 32.0f);
        EXPECT_EQ(v.at(l.outsideHead), -1000.0f);
        EXPECT_EQ(v.at(l.maxillarySinus), -1000.0f);
        EXPECT_GT(v.at(l.upperMolarCrown), 2000.0f);
    }
}

TEST(Phantom, SparseGridHoldsTheTissueOnly)
{
    // The default 512 x 512 x 256 phantom.
    DenseScan scan = makePhantomScan(PhantomOptions{});
    ASSERT_EQ(scan.geometry.dims, Coord(512, 512, 256));
    uint64_t tissue = 0;
    for (float v : scan.values) tissue += v > -500.0f;
    const Volume vol = makeVolume(std::move(scan), "phantom");
    EXPECT_EQ(vol.airThreshold, -500.0f);
    const VolumeStats stats = computeStats(vol);
    EXPECT_EQ(stats.activeVoxels, tissue);
    const uint64_t voxels = uint64_t(512) * 512 * 256;
    EXPECT_EQ(stats.denseBytes, voxels * 4);
    // Measured (seed 1): 18,883,063 active voxels (28.1 %); grid memUsage 106,919,652 B
    // = 0.398 x the 256 MiB dense array. Asserted with margin for small anatomy changes.
    EXPECT_GT(tissue, voxels * 25 / 100);
    EXPECT_LT(tissue, voxels * 32 / 100);
    EXPECT_LT(double(stats.memoryBytes), 0.45 * double(stats.denseBytes));
    EXPECT_GT(double(stats.memoryBytes), 0.30 * double(stats.denseBytes));
    EXPECT_GE(stats.suggestedBoneIso, 150.0f);
    EXPECT_LE(stats.suggestedBoneIso, 700.0f);
}

TEST(Phantom, BonePiecesAreSkullMandibleAndVertebrae)
{
    const PhantomLandmarks l = phantomLandmarks();
    const DenseScan scan = makePhantomScan(options(Coord(128, 128, 128), 1));
    const Components c = bonePieces(scan, 400.0f);
    const DenseView v{scan};
    const auto labelAt = [&](const Vec3d& w) { return c.label[v.offset(v.ijkOf(w))]; };
    // Skull, maxilla and upper teeth are one piece; mandible and lower teeth another;
    // each of the 7 vertebrae is its own piece; no specks.
    EXPECT_EQ(c.count, 9);
    const int skull = labelAt(l.skullLateral);
    const int mandible = labelAt(l.mandibleBone);
    EXPECT_NE(skull, 0);
    EXPECT_NE(mandible, 0);
    EXPECT_NE(skull, mandible);
    EXPECT_EQ(labelAt(l.vertexBone), skull);
    EXPECT_EQ(labelAt(l.maxillaBone), skull);
    EXPECT_EQ(labelAt(l.upperIncisorCrown), skull);
    EXPECT_EQ(labelAt(l.upperMolarCrown), skull);
    EXPECT_EQ(labelAt(l.lowerIncisorCrown), mandible);
    std::vector<int> vertebrae;
    ASSERT_EQ(l.vertebraBodies.size(), 7u);
    for (int k = 0; k < 7; ++k) {
        const int id = labelAt(l.vertebraBodies[k]);
        EXPECT_NE(id, 0) << "vertebra " << k;
        EXPECT_NE(id, skull);
        EXPECT_NE(id, mandible);
        vertebrae.push_back(id);
    }
    std::sort(vertebrae.begin(), vertebrae.end());
    EXPECT_EQ(std::unique(vertebrae.begin(), vertebrae.end()), vertebrae.end());
}

TEST(Phantom, ReportsProgressAndCancels)
{
    RecordingInterrupter progress;
    const DenseScan scan = makePhantomScan(options(Coord(32, 32, 40)), &progress);
    ASSERT_EQ(progress.names.size(), 1u);
    EXPECT_EQ(progress.names[0], "phantom");
    EXPECT_EQ(progress.percents.size(), 40u + 1u); // one poll per slice, then 100
    EXPECT_EQ(progress.percents.back(), 100);
    for (int p : progress.percents) {
        EXPECT_GE(p, 0);
        EXPECT_LE(p, 100);
    }

    RecordingInterrupter cancel(3);
    EXPECT_THROW(makePhantomScan(options(Coord(32, 32, 40)), &cancel), Cancelled);
    EXPECT_LT(cancel.percents.size(), 40u);
}
