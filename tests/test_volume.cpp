// vdb::makeVolume: canonical orientation, sparsity that keeps exact values
// near tissue, rejection of bad geometry and NaN, and the .vdb round trip.
#include "TestUtil.h"

#include "vdb/Formats.h"
#include "vdb/Volume.h"
#include "vdb/VolumeIO.h"

#include <openvdb/tools/Dense.h>

#include <cmath>
#include <random>

using namespace mtcut;
using namespace mtcut::vdb;
using mtcut::test::TempDir;
using openvdb::Coord;
using openvdb::Vec3d;

namespace {

/// A small scan in file order with a value that identifies each voxel.
DenseScan makeScan(Coord dims, uint32_t seed = 7)
{
    DenseScan scan;
    scan.geometry.dims = dims;
    scan.geometry.spacing = Vec3d(0.5, 0.75, 2.0);
    scan.geometry.origin = Vec3d(-10.0, 20.0, 30.0);
    scan.values.resize(size_t(dims[0]) * dims[1] * dims[2]);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-1000.0f, 2000.0f);
    for (float& v : scan.values) v = u(rng);
    return scan;
}

float fileValue(const DenseScan& s, int i, int j, int k)
{
    const Coord& d = s.geometry.dims;
    return s.values[(size_t(k) * d[1] + j) * d[0] + i];
}

} // namespace

TEST(Volume, IdentityOrientationKeepsEveryValueAndWorldPosition)
{
    const DenseScan scan = makeScan(Coord(11, 9, 7));
    DenseScan copy = scan;
    const Volume vol = makeVolume(std::move(copy), "mem", SparseOptions{-2000.0f});
    EXPECT_EQ(vol.dims, Coord(11, 9, 7));
    EXPECT_EQ(vol.spacing(), Vec3d(0.5, 0.75, 2.0));
    EXPECT_EQ(vol.origin(), Vec3d(-10.0, 20.0, 30.0));
    auto acc = vol.grid->getConstAccessor();
    for (int k = 0; k < 7; ++k)
        for (int j = 0; j < 9; ++j)
            for (int i = 0; i < 11; ++i) ASSERT_EQ(acc.getValue(Coord(i, j, k)), fileValue(scan, i, j, k));
    // Every voxel is above the -2000 air threshold, so all are active.
    EXPECT_EQ(vol.grid->activeVoxelCount(), 11u * 9u * 7u);
}

// A file whose axes are flipped and permuted must land on the same world
// positions with the same values: the canonical grid's axes point along
// +x, +y, +z and its transform is a pure scale and translation.
TEST(Volume, FlipsAndPermutationsAreCanonicalised)
{
    const DenseScan plain = makeScan(Coord(6, 5, 4));
    const Volume ref = makeVolume(DenseScan(plain), "plain", SparseOptions{-2000.0f});

    // File axis i runs along world -z, j along +x, k along -y.
    DenseScan odd;
    const Coord d = plain.geometry.dims; // canonical (x, y, z) sizes
    odd.geometry.dims = Coord(d[2], d[0], d[1]);
    odd.geometry.spacing = Vec3d(2.0, 0.5, 0.75);
    odd.geometry.direction = openvdb::Mat3d(0.0, 1.0, 0.0, // row x: (i, j, k) components
                                            0.0, 0.0, -1.0, // row y
                                            -1.0, 0.0, 0.0); // row z
    // World of file voxel (0,0,0) is the canonical voxel (0, d.y-1, d.z-1).
    odd.geometry.origin = Vec3d(-10.0, 20.0 + 0.75 * (d[1] - 1), 30.0 + 2.0 * (d[2] - 1));
    odd.values.resize(plain.values.size());
    for (int fk = 0; fk < d[1]; ++fk)
        for (int fj = 0; fj < d[0]; ++fj)
            for (int fi = 0; fi < d[2]; ++fi) {
                const int x = fj, y = d[1] - 1 - fk, z = d[2] - 1 - fi;
                odd.values[(size_t(fk) * d[0] + fj) * d[2] + fi] = fileValue(plain, x, y, z);
            }
    const Volume vol = makeVolume(std::move(odd), "odd", SparseOptions{-2000.0f});
    EXPECT_EQ(vol.dims, ref.dims);
    EXPECT_EQ(vol.spacing(), ref.spacing());
    EXPECT_LT((vol.origin() - ref.origin()).length(), 1e-9);
    auto a = vol.grid->getConstAccessor();
    auto b = ref.grid->getConstAccessor();
    for (auto c = ref.indexBox().begin(); c; ++c) ASSERT_EQ(a.getValue(*c), b.getValue(*c)) << *c;
}

TEST(Volume, ObliqueOrientationIsRejected)
{
    DenseScan scan = makeScan(Coord(4, 4, 4));
    const double c = std::cos(0.1), s = std::sin(0.1);
    scan.geometry.direction = openvdb::Mat3d(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
    try {
        makeVolume(std::move(scan), "tilted.nrrd");
        FAIL() << "oblique scan accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("tilted.nrrd: oblique orientation"), std::string::npos) << e.what();
    }
}

TEST(Volume, NaNAndInfinityAreRejectedNamingTheVoxel)
{
    DenseScan scan = makeScan(Coord(5, 4, 3));
    scan.values[(size_t(2) * 4 + 1) * 5 + 3] = std::nanf("");
    try {
        makeVolume(DenseScan(scan), "scan.raw");
        FAIL();
    } catch (const InputError& e) {
        EXPECT_STREQ(e.what(), "scan.raw: voxel (3, 1, 2) is NaN; the volume must hold finite values");
    }
    scan.values[(size_t(2) * 4 + 1) * 5 + 3] = INFINITY;
    EXPECT_THROW(makeVolume(std::move(scan), "scan.raw"), InputError);
}

TEST(Volume, BadGeometryIsRejectedBeforeAllocating)
{
    EXPECT_THROW(checkDims(Coord(0, 10, 10), "f"), InputError);
    EXPECT_THROW(checkDims(Coord(10, -3, 10), "f"), InputError);
    EXPECT_THROW(checkDims(Coord(100000, 100000, 100000), "f"), InputError);
    EXPECT_THROW(checkDims(Coord(70000, 1, 1), "f"), InputError);
    EXPECT_NO_THROW(checkDims(Coord(512, 512, 600), "f"));
    DenseScan scan = makeScan(Coord(3, 3, 3));
    scan.geometry.spacing = Vec3d(1.0, 0.0, 1.0);
    EXPECT_THROW(makeVolume(DenseScan(scan), "f"), InputError);
    scan.geometry.spacing = Vec3d(1.0, 1.0, 1.0);
    scan.values.pop_back();
    EXPECT_THROW(makeVolume(std::move(scan), "f"), InputError);
}

// Air far from tissue becomes inactive background tiles; every voxel within
// one leaf (8 voxels) of a voxel above the air threshold keeps its exact value.
TEST(Volume, SparsityKeepsExactValuesNearTissue)
{
    const Coord dims(64, 48, 40);
    DenseScan scan;
    scan.geometry.dims = dims;
    scan.units = "HU";
    scan.values.resize(size_t(dims[0]) * dims[1] * dims[2]);
    std::mt19937 rng(3);
    std::normal_distribution<float> noise(0.0f, 20.0f);
    for (int k = 0; k < dims[2]; ++k)
        for (int j = 0; j < dims[1]; ++j)
            for (int i = 0; i < dims[0]; ++i) {
                const double r = std::sqrt(std::pow(i - 20.0, 2) + std::pow(j - 20.0, 2) + std::pow(k - 18.0, 2));
                scan.values[(size_t(k) * dims[1] + j) * dims[0] + i] =
                    (r < 9.0 ? 800.0f : -1000.0f) + noise(rng);
            }
    const DenseScan original = scan;
    const Volume vol = makeVolume(std::move(scan), "ball");
    EXPECT_EQ(vol.units, "HU");
    EXPECT_EQ(vol.airThreshold, -500.0f);
    EXPECT_EQ(vol.grid->background(), vol.minValue);

    auto acc = vol.grid->getConstAccessor();
    uint64_t active = 0;
    for (int k = 0; k < dims[2]; ++k)
        for (int j = 0; j < dims[1]; ++j)
            for (int i = 0; i < dims[0]; ++i) {
                const float v = fileValue(original, i, j, k);
                const Coord c(i, j, k);
                active += v > -500.0f;
                ASSERT_EQ(acc.isValueOn(c), v > -500.0f) << c;
                const double r = std::sqrt(std::pow(i - 20.0, 2) + std::pow(j - 20.0, 2) + std::pow(k - 18.0, 2));
                if (r < 9.0 + 8.0) ASSERT_EQ(acc.getValue(c), v) << c;               // near tissue: exact
                else ASSERT_TRUE(acc.getValue(c) == v || acc.getValue(c) == vol.minValue) << c; // far: pruned
            }
    EXPECT_EQ(vol.grid->activeVoxelCount(), active);
    // The far corner block holds no tissue nor touches any: it must be a tile.
    EXPECT_EQ(acc.probeConstLeaf(Coord(56, 40, 32)), nullptr);
    // Exactly the blocks that hold or touch (26-neighbourhood) a block with tissue are leaves.
    const Coord nb(8, 6, 5);
    std::vector<int> tissue(size_t(nb[0]) * nb[1] * nb[2], 0);
    for (int k = 0; k < dims[2]; ++k)
        for (int j = 0; j < dims[1]; ++j)
            for (int i = 0; i < dims[0]; ++i)
                if (fileValue(original, i, j, k) > -500.0f) tissue[size_t(k / 8 * nb[1] + j / 8) * nb[0] + i / 8] = 1;
    size_t expectedLeaves = 0;
    for (int z = 0; z < nb[2]; ++z)
        for (int y = 0; y < nb[1]; ++y)
            for (int x = 0; x < nb[0]; ++x) {
                bool near = false;
                for (int dz = -1; dz <= 1; ++dz)
                    for (int dy = -1; dy <= 1; ++dy)
                        for (int dx = -1; dx <= 1; ++dx) {
                            const int a = x + dx, b = y + dy, c = z + dz;
                            if (a >= 0 && b >= 0 && c >= 0 && a < nb[0] && b < nb[1] && c < nb[2])
                                near = near || tissue[size_t(c * nb[1] + b) * nb[0] + a];
                        }
                expectedLeaves += near;
                EXPECT_EQ(acc.probeConstLeaf(Coord(x * 8, y * 8, z * 8)) != nullptr, near) << x << "," << y << "," << z;
            }
    EXPECT_EQ(vol.grid->tree().leafCount(), expectedLeaves);
    EXPECT_LT(expectedLeaves, size_t(nb[0]) * nb[1] * nb[2]);
}

TEST(Volume, ToDenseInvertsMakeVolume)
{
    DenseScan scan = makeScan(Coord(13, 10, 9));
    const DenseScan original = scan;
    const Volume vol = makeVolume(std::move(scan), "mem", SparseOptions{-5000.0f});
    const DenseScan back = toDense(vol);
    EXPECT_EQ(back.geometry.dims, original.geometry.dims);
    EXPECT_EQ(back.values, original.values);
}

TEST(Volume, VdbRoundTripKeepsGridAndFields)
{
    TempDir dir;
    const Volume vol = makeVolume(makeScan(Coord(20, 17, 9)), "mem");
    const std::string path = dir.file("v.vdb");
    writeVolume(vol, path);
    const Volume back = readVolume(path);
    EXPECT_EQ(back.dims, vol.dims);
    EXPECT_EQ(back.spacing(), vol.spacing());
    EXPECT_EQ(back.origin(), vol.origin());
    EXPECT_EQ(back.airThreshold, vol.airThreshold);
    EXPECT_EQ(back.minValue, vol.minValue);
    EXPECT_EQ(back.maxValue, vol.maxValue);
    EXPECT_EQ(back.units, vol.units);
    EXPECT_EQ(toDense(back).values, toDense(vol).values);
    EXPECT_EQ(back.grid->activeVoxelCount(), vol.grid->activeVoxelCount());
}

TEST(Volume, ForeignVdbGridIsShiftedToTheOrigin)
{
    openvdb::initialize();
    TempDir dir;
    auto grid = openvdb::FloatGrid::create(-1000.0f);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(0.5));
    grid->tree().setValue(Coord(-3, 4, 10), 700.0f);
    grid->tree().setValue(Coord(2, 6, 12), 300.0f);
    grid->setName("ct");
    openvdb::io::File(dir.file("f.vdb")).write({grid});
    const Volume vol = readVolume(dir.file("f.vdb"));
    EXPECT_EQ(vol.dims, Coord(6, 3, 3));
    EXPECT_EQ(vol.grid->tree().getValue(Coord(0, 0, 0)), 700.0f);
    EXPECT_EQ(vol.grid->tree().getValue(Coord(5, 2, 2)), 300.0f);
    // World positions are unchanged by the shift.
    EXPECT_LT((vol.grid->indexToWorld(Coord(0, 0, 0)) - Vec3d(-1.5, 2.0, 5.0)).length(), 1e-12);

    ReadOptions named;
    named.gridName = "nothere";
    EXPECT_THROW(readVolume(dir.file("f.vdb"), named), InputError);
}

TEST(Volume, SuggestedBoneIsovalueSplitsTissueFromBone)
{
    const Coord dims(40, 40, 40);
    DenseScan scan;
    scan.geometry.dims = dims;
    scan.units = "HU";
    scan.values.assign(size_t(dims[0]) * dims[1] * dims[2], -1000.0f);
    for (int k = 5; k < 35; ++k)
        for (int j = 5; j < 35; ++j)
            for (int i = 5; i < 35; ++i) {
                const bool bone = i < 12;
                scan.values[(size_t(k) * dims[1] + j) * dims[0] + i] = bone ? 1200.0f : 40.0f;
            }
    const Volume vol = makeVolume(std::move(scan), "blocks");
    const VolumeStats stats = computeStats(vol);
    EXPECT_GT(stats.suggestedBoneIso, 40.0f);
    EXPECT_LT(stats.suggestedBoneIso, 1200.0f);
    EXPECT_EQ(stats.activeVoxels, 30u * 30u * 30u);
    EXPECT_EQ(stats.denseBytes, 40u * 40u * 40u * 4u);
}
