// Write-back of a cut: cut.vdb (fragment level sets, cut mask, carved volume,
// metadata) and slices.exr (multi-part slice stack), read back with OpenVDB
// and OpenEXR themselves.
#include "TestUtil.h"

#include "vdb/CutOutputs.h"
#include "vdb/Error.h"
#include "vdb/SliceExr.h"
#include "vdb/VolumeIO.h"

#include <ImfChannelList.h>
#include <ImfDoubleAttribute.h>
#include <ImfFloatAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputPart.h>
#include <ImfIntAttribute.h>
#include <ImfMultiPartInputFile.h>
#include <ImfThreading.h>
#include <ImfPartType.h>
#include <ImfStringAttribute.h>
#include <ImfVecAttribute.h>

#include <openvdb/io/File.h>
#include <openvdb/tools/Diagnostics.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <mutex>
#include <regex>

using namespace mtcut;
using namespace mtcut::vdb;
using openvdb::Coord;
using openvdb::CoordBBox;
namespace fs = std::filesystem;

namespace {

constexpr float kAir = -1000.0f;

/// 40^3 voxels of 0.5 x 0.5 x 1 mm, origin (-10,-10,-20): a ball of radius 8 mm
/// at the world origin whose values differ per voxel (1000 + i + j/4), air -1000.
Volume makeBall()
{
    DenseScan scan;
    scan.geometry.dims = Coord(40, 40, 40);
    scan.geometry.spacing = openvdb::Vec3d(0.5, 0.5, 1.0);
    scan.geometry.origin = openvdb::Vec3d(-10.0, -10.0, -20.0);
    scan.units = "HU";
    scan.values.resize(40 * 40 * 40);
    for (int k = 0; k < 40; ++k)
        for (int j = 0; j < 40; ++j)
            for (int i = 0; i < 40; ++i) {
                const openvdb::Vec3d w(-10.0 + 0.5 * i, -10.0 + 0.5 * j, -20.0 + k);
                scan.values[size_t(i + 40 * (j + 40 * k))] = w.length() <= 8.0 ? 1000.0f + float(i) + 0.25f * float(j)
                                                                                : kAir;
            }
    return makeVolume(std::move(scan), "ball");
}

/// An axis-aligned box [lo, hi] (world mm) as 8 vertices and 12 triangles, CCW outward.
struct BoxMesh
{
    std::vector<float> positions;
    std::vector<uint32_t> triangles;

    BoxMesh(const openvdb::Vec3f& lo, const openvdb::Vec3f& hi)
    {
        for (int v = 0; v < 8; ++v) { // vertex v = ix + 2 iy + 4 iz
            positions.push_back(v & 1 ? hi.x() : lo.x());
            positions.push_back(v & 2 ? hi.y() : lo.y());
            positions.push_back(v & 4 ? hi.z() : lo.z());
        }
        const uint32_t quads[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                      {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
        for (const auto& q : quads) triangles.insert(triangles.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
    }
    FragmentMesh view() const { return {positions.data(), positions.size() / 3, triangles.data(), triangles.size() / 3}; }
};

/// Voxels removed by the cut: the slab i = 18..21, one aligned 8^3 block
/// (stored as a tile) and two voxels outside the scan (ignored).
openvdb::MaskGrid::Ptr makeRemoved()
{
    auto removed = openvdb::MaskGrid::create();
    removed->tree().fill(CoordBBox(Coord(18, 0, 0), Coord(21, 39, 39)), true, true);
    removed->tree().fill(CoordBBox(Coord(8, 8, 8), Coord(15, 15, 15)), true, true);
    removed->tree().setValueOn(Coord(-3, 0, 0));
    removed->tree().setValueOn(Coord(50, 50, 50));
    return removed;
}

bool isRemoved(const Coord& c)
{
    return (c.x() >= 18 && c.x() <= 21) || CoordBBox(Coord(8), Coord(15)).isInside(c);
}

const std::map<Coord, int32_t> kMaskVoxels = {{Coord(19, 20, 20), 1}, {Coord(20, 20, 20), 1},
                                              {Coord(20, 21, 20), 2}, {Coord(5, 6, 7), 2},
                                              {Coord(0, 39, 39), 3}};

openvdb::Int32Grid::Ptr makeMask()
{
    auto mask = openvdb::Int32Grid::create(0);
    for (const auto& [c, id] : kMaskVoxels) mask->tree().setValueOn(c, id);
    return mask;
}

struct Scene
{
    Volume volume = makeBall();
    openvdb::FloatGrid::Ptr carved = carveVolume(volume, *makeRemoved());
    openvdb::Int32Grid::Ptr mask = makeMask();
    BoxMesh boxA{{-6, -4, -4}, {-1, 4, 4}}; // 320 mm^3, 288 mm^2
    BoxMesh boxB{{1, -3, -3}, {5, 3, 3}};   // 144 mm^3, 168 mm^2
    CutInfo info{300.0f, 0.75f, "lefort.path"};
};

std::vector<std::string> filesIn(const std::string& dir)
{
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
    return names;
}

/// Asks to stop on the n-th poll.
class StopAfter : public Interrupter
{
public:
    explicit StopAfter(int n) : mLeft(n) {}
    bool wasInterrupted(int = -1) override { return --mLeft < 0; }

private:
    std::atomic<int> mLeft;
};

/// Records the phases started and the percentages reported (from any thread).
class Recorder : public Interrupter
{
public:
    void start(const char* name = nullptr) override
    {
        std::lock_guard<std::mutex> lock(mMutex);
        phases.push_back(name ? name : "");
    }
    bool wasInterrupted(int percent = -1) override
    {
        std::lock_guard<std::mutex> lock(mMutex);
        if (percent >= 0) percents.push_back(percent);
        return false;
    }
    std::vector<std::string> phases;
    std::vector<int> percents;

private:
    std::mutex mMutex;
};

} // namespace

TEST(CarveVolume, RemovedVoxelsBecomeInactiveBackgroundOthersKeepExactValues)
{
    const Volume volume = makeBall();
    const openvdb::FloatGrid::Ptr carved = carveVolume(volume, *makeRemoved());
    ASSERT_EQ(carved->transform(), volume.grid->transform());
    EXPECT_EQ(carved->background(), kAir);
    auto in = volume.grid->getConstAccessor();
    auto out = carved->getConstAccessor();
    size_t removedCount = 0;
    for (auto it = volume.indexBox().begin(); it; ++it) {
        const Coord c = *it;
        if (isRemoved(c)) {
            ++removedCount;
            EXPECT_EQ(out.getValue(c), kAir) << c;
            EXPECT_FALSE(out.isValueOn(c)) << c;
        } else {
            EXPECT_EQ(out.getValue(c), in.getValue(c)) << c;
            EXPECT_EQ(out.isValueOn(c), in.isValueOn(c)) << c;
        }
    }
    EXPECT_EQ(removedCount, 4u * 40 * 40 + 8u * 8 * 8); // slab and block are disjoint
    // The removed voxels outside the scan added nothing; the volume itself is untouched.
    EXPECT_EQ(carved->tree().probeConstLeaf(Coord(50, 50, 50)), nullptr);
    EXPECT_EQ(carved->tree().probeConstLeaf(Coord(-3, 0, 0)), nullptr);
    EXPECT_EQ(in.getValue(Coord(20, 20, 20)), 1000.0f + 20.0f + 5.0f);
    EXPECT_TRUE(in.isValueOn(Coord(20, 20, 20)));
}

TEST(CutVdb, GridsMetadataLevelSetsMaskAndCarvedReadBack)
{
    const Scene s;
    test::TempDir dir;
    const std::string path = dir.file("cut.vdb");
    writeCutVdb(path, s.volume, *s.carved, *s.mask, {s.boxA.view(), s.boxB.view()}, s.info);
    EXPECT_EQ(filesIn(dir.path()), std::vector<std::string>{"cut.vdb"});

    openvdb::io::File file(path);
    file.open();
    const openvdb::MetaMap::Ptr meta = file.getMetadata();
    const openvdb::GridPtrVecPtr grids = file.getGrids();
    file.close();

    // File metadata.
    EXPECT_EQ(meta->metaValue<std::string>("mtcut:version"), std::string(kMtcutVersion));
    EXPECT_TRUE(std::regex_match(std::string(kMtcutVersion), std::regex(R"(\d+\.\d+\.\d+)"))) << kMtcutVersion;
    EXPECT_EQ(meta->metaValue<float>("mtcut:isovalue"), 300.0f);
    EXPECT_EQ(meta->metaValue<float>("mtcut:kerf_mm"), 0.75f);
    EXPECT_EQ(meta->metaValue<std::string>("mtcut:path_file"), "lefort.path");
    EXPECT_EQ(meta->metaValue<int32_t>("mtcut:fragments"), 2);

    // Grid names, order, types and classes.
    ASSERT_EQ(grids->size(), 4u);
    const std::vector<std::string> names = {"carved", "cut_mask", "fragment_000", "fragment_001"};
    for (size_t g = 0; g < 4; ++g) EXPECT_EQ((*grids)[g]->getName(), names[g]);
    auto carved = openvdb::gridPtrCast<openvdb::FloatGrid>((*grids)[0]);
    auto mask = openvdb::gridPtrCast<openvdb::Int32Grid>((*grids)[1]);
    auto lsA = openvdb::gridPtrCast<openvdb::FloatGrid>((*grids)[2]);
    auto lsB = openvdb::gridPtrCast<openvdb::FloatGrid>((*grids)[3]);
    ASSERT_TRUE(carved && mask && lsA && lsB);
    EXPECT_EQ(carved->getGridClass(), openvdb::GRID_UNKNOWN);
    EXPECT_EQ(mask->getGridClass(), openvdb::GRID_UNKNOWN);
    EXPECT_EQ(lsA->getGridClass(), openvdb::GRID_LEVEL_SET);
    EXPECT_EQ(lsB->getGridClass(), openvdb::GRID_LEVEL_SET);

    // Per-fragment metadata, exact for boxes.
    EXPECT_DOUBLE_EQ(lsA->metaValue<double>("mtcut:volume_mm3"), 320.0);
    EXPECT_DOUBLE_EQ(lsA->metaValue<double>("mtcut:area_mm2"), 288.0);
    EXPECT_EQ(lsA->metaValue<int64_t>("mtcut:triangles"), 12);
    EXPECT_DOUBLE_EQ(lsB->metaValue<double>("mtcut:volume_mm3"), 144.0);
    EXPECT_DOUBLE_EQ(lsB->metaValue<double>("mtcut:area_mm2"), 168.0);
    EXPECT_EQ(lsB->metaValue<int64_t>("mtcut:triangles"), 12);

    // Level sets: uniform 0.5 mm (the smallest spacing), half-width 3 voxels, valid.
    for (const auto& ls : {lsA, lsB}) {
        EXPECT_EQ(ls->voxelSize(), openvdb::Vec3d(0.5));
        EXPECT_FLOAT_EQ(ls->background(), 1.5f);
        // Checks 1-8 (type, class, uniform scale, background, no active tiles, finite,
        // range, symmetric band); 9 (|grad| ~ 1) fails by nature along a box's sharp edges.
        EXPECT_EQ(openvdb::tools::checkLevelSet(*ls, 8), "");
    }
    // Signed distances (mm) at voxel centres near box A's face x = -1, away from edges.
    auto sample = [](const openvdb::FloatGrid& g, const openvdb::Vec3d& world) {
        const openvdb::Vec3d ijk = g.worldToIndex(world);
        const Coord c = Coord::round(ijk);
        EXPECT_TRUE((ijk - c.asVec3d()).length() < 1e-9) << world << " is not a voxel centre";
        return g.tree().getValue(c);
    };
    EXPECT_NEAR(sample(*lsA, {-1.5, 0, 0}), -0.5f, 1e-5);
    EXPECT_NEAR(sample(*lsA, {-2.0, 0, 0}), -1.0f, 1e-5);
    EXPECT_NEAR(sample(*lsA, {-0.5, 0, 0}), 0.5f, 1e-5);
    EXPECT_NEAR(sample(*lsA, {0.0, 0, 0}), 1.0f, 1e-5);
    EXPECT_EQ(sample(*lsA, {-3.5, 0, 0}), -1.5f); // deep inside: -background
    EXPECT_EQ(sample(*lsA, {8.0, 0, 0}), 1.5f);   // far outside: +background
    EXPECT_NEAR(sample(*lsB, {4.5, 0, 0}), -0.5f, 1e-5);
    EXPECT_NEAR(sample(*lsB, {1.0, 0, 0}), 0.0f, 1e-5);
    EXPECT_NEAR(sample(*lsB, {0.0, 0, 0}), 1.0f, 1e-5);
    EXPECT_EQ(sample(*lsB, {3.0, 0, 0}), -1.5f);
    EXPECT_EQ(sample(*lsB, {-3.5, 0, 0}), 1.5f); // inside A is outside B

    // Cut mask: the volume's transform, exactly the given voxels and ids.
    EXPECT_EQ(mask->transform(), s.volume.grid->transform());
    std::map<Coord, int32_t> readMask;
    for (auto it = mask->cbeginValueOn(); it; ++it) readMask[it.getCoord()] = *it;
    EXPECT_EQ(readMask, kMaskVoxels);

    // Carved: bit-exact equal to carveVolume's result, the volume's transform and fields.
    EXPECT_EQ(carved->transform(), s.volume.grid->transform());
    EXPECT_EQ(carved->background(), kAir);
    EXPECT_EQ(carved->activeVoxelCount(), s.carved->activeVoxelCount());
    auto ref = s.carved->getConstAccessor();
    for (auto it = s.volume.indexBox().begin(); it; ++it) {
        ASSERT_EQ(carved->tree().getValue(*it), ref.getValue(*it)) << *it;
        ASSERT_EQ(carved->tree().isValueOn(*it), ref.isValueOn(*it)) << *it;
    }
    EXPECT_EQ(carved->metaValue<openvdb::Vec3i>("mtcut:dims"), openvdb::Vec3i(40, 40, 40));
    EXPECT_EQ(carved->metaValue<std::string>("mtcut:units"), "HU");
    EXPECT_EQ(carved->metaValue<float>("mtcut:air_threshold"), s.volume.airThreshold);
    EXPECT_EQ(carved->metaValue<float>("mtcut:min"), kAir);
    EXPECT_EQ(carved->metaValue<float>("mtcut:max"), s.volume.maxValue);
    EXPECT_EQ(carved->metaValue<std::string>("mtcut:source"), "ball");
}

TEST(CutVdb, CarvedGridReadsBackAsAVolume)
{
    const Scene s;
    test::TempDir dir;
    const std::string path = dir.file("cut.vdb");
    writeCutVdb(path, s.volume, *s.carved, *s.mask, {s.boxA.view()}, s.info);
    for (const std::string& grid : {std::string("carved"), std::string()}) { // carved is the first float grid
        ReadOptions options;
        options.gridName = grid;
        const Volume back = readVolume(path, options);
        EXPECT_EQ(back.dims, s.volume.dims);
        EXPECT_EQ(back.units, "HU");
        EXPECT_EQ(back.airThreshold, s.volume.airThreshold);
        EXPECT_EQ(back.minValue, s.volume.minValue);
        EXPECT_EQ(back.maxValue, s.volume.maxValue);
        EXPECT_EQ(back.spacing(), s.volume.spacing());
        EXPECT_EQ(back.origin(), s.volume.origin());
        EXPECT_EQ(back.grid->tree().getValue(Coord(20, 20, 20)), kAir);
        EXPECT_EQ(back.grid->tree().getValue(Coord(16, 20, 20)), 1000.0f + 16.0f + 5.0f);
    }
    const test::RunResult r = test::runMtcut("info '" + path + "' --grid carved");
    EXPECT_EQ(r.exitCode, 0) << r.output;
    EXPECT_NE(r.output.find("grid:      40 x 40 x 40 voxels"), std::string::npos) << r.output;
}

TEST(CutVdb, LevelSetVoxelSizeIsAnOption)
{
    const Scene s;
    test::TempDir dir;
    CutVdbOptions options;
    options.levelSetVoxelMm = 0.25;
    options.halfWidthVoxels = 4.0f;
    writeCutVdb(dir.file("cut.vdb"), s.volume, *s.carved, *s.mask, {s.boxB.view()}, s.info, options);
    openvdb::io::File file(dir.file("cut.vdb"));
    file.open();
    auto ls = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("fragment_000"));
    file.close();
    ASSERT_TRUE(ls);
    EXPECT_EQ(ls->voxelSize(), openvdb::Vec3d(0.25));
    EXPECT_FLOAT_EQ(ls->background(), 1.0f);
    EXPECT_NEAR(ls->tree().getValue(Coord::round(ls->worldToIndex({4.75, 0, 0}))), -0.25f, 1e-5);

    options.levelSetVoxelMm = -1.0;
    EXPECT_THROW(writeCutVdb(dir.file("bad.vdb"), s.volume, *s.carved, *s.mask, {}, s.info, options), InputError);
    options.levelSetVoxelMm = 0.0;
    options.halfWidthVoxels = 0.5f;
    EXPECT_THROW(writeCutVdb(dir.file("bad.vdb"), s.volume, *s.carved, *s.mask, {}, s.info, options), InputError);
    EXPECT_EQ(filesIn(dir.path()), std::vector<std::string>{"cut.vdb"});
}

// Some fragments written (the viewer's "save selected", `mtcut cut
// --min-volume`): each level set is named by its fragment's number, as its
// file is, not by its position in the list; a bad one is reported by it.
TEST(CutVdb, LevelSetsOfSomeFragmentsKeepTheirNumbers)
{
    const Scene s;
    test::TempDir dir;
    const std::string path = dir.file("cut.vdb");
    FragmentMesh a = s.boxA.view(), b = s.boxB.view();
    a.index = 2;
    b.index = 7;
    writeCutVdb(path, s.volume, *s.carved, *s.mask, {a, b}, s.info);
    openvdb::io::File file(path);
    file.open();
    std::vector<std::string> names;
    for (auto it = file.beginName(); it != file.endName(); ++it) names.push_back(it.gridName());
    file.close();
    EXPECT_EQ(names, (std::vector<std::string>{"carved", "cut_mask", "fragment_002", "fragment_007"}));
    FragmentMesh bad;
    bad.index = 5;
    try {
        writeCutVdb(dir.file("bad.vdb"), s.volume, *s.carved, *s.mask, {a, bad}, s.info);
        ADD_FAILURE() << "no error for an empty fragment";
    } catch (const InputError& e) {
        EXPECT_EQ(std::string(e.what()), "fragment 5: mesh has no triangles");
    }
}

TEST(CutVdb, BadFragmentsAreInputErrorsAndWriteNothing)
{
    const Scene s;
    test::TempDir dir;
    const std::string path = dir.file("cut.vdb");
    auto expectError = [&](const FragmentMesh& bad, const std::string& message) {
        try {
            writeCutVdb(path, s.volume, *s.carved, *s.mask, {s.boxA.view(), bad}, s.info);
            ADD_FAILURE() << "no error for " << message;
        } catch (const InputError& e) {
            EXPECT_EQ(std::string(e.what()), message);
        }
        EXPECT_TRUE(filesIn(dir.path()).empty());
    };
    expectError(FragmentMesh{}, "fragment 1: mesh has no triangles");

    BoxMesh outOfRange = s.boxB;
    outOfRange.triangles[3 * 5 + 1] = 8;
    expectError(outOfRange.view(), "fragment 1: triangle 5 uses vertex 8, but the mesh has 8 vertices");

    BoxMesh flat({1, 1, 1}, {1, 1, 1}); // every vertex at one point
    expectError(flat.view(), "fragment 1: mesh is degenerate (all 12 triangles have zero area)");

    BoxMesh nan = s.boxB;
    nan.positions[3 * 6 + 2] = std::nanf("");
    expectError(nan.view(), "fragment 1: vertex 6 has a non-finite coordinate");

    EXPECT_THROW(checkFragmentMesh(outOfRange.view(), 7), InputError);
    const FragmentStats stats = checkFragmentMesh(s.boxB.view(), 0);
    EXPECT_DOUBLE_EQ(stats.volumeMm3, 144.0);
}

TEST(CutVdb, UnwritablePathIsAnInputErrorAndCancelLeavesNothing)
{
    const Scene s;
    test::TempDir dir;
    { std::ofstream(dir.file("plain")) << "x"; }
    const std::string path = dir.file("plain") + "/cut.vdb"; // parent is a file
    try {
        writeCutVdb(path, s.volume, *s.carved, *s.mask, {s.boxA.view()}, s.info);
        ADD_FAILURE() << "no error";
    } catch (const InputError& e) {
        EXPECT_EQ(std::string(e.what()).rfind(path + ": cannot write VDB (", 0), 0u) << e.what();
    }
    EXPECT_EQ(filesIn(dir.path()), std::vector<std::string>{"plain"});

    StopAfter stop(1);
    EXPECT_THROW(writeCutVdb(dir.file("cut.vdb"), s.volume, *s.carved, *s.mask, {s.boxA.view(), s.boxB.view()},
                             s.info, {}, &stop),
                 Cancelled);
    EXPECT_EQ(filesIn(dir.path()), std::vector<std::string>{"plain"});
}

// The level sets' progress counts fragments done, up to 100 and never back:
// each fragment's meshToVolume only answers whether to stop (its own
// percentages, 30 to 94 for every fragment, ran the bar back and forth).
TEST(CutVdb, ProgressCountsFragmentsAndNeverGoesBack)
{
    const Scene s;
    test::TempDir dir;
    Recorder recorder;
    const std::vector<FragmentMesh> fragments = {s.boxA.view(), s.boxB.view(), s.boxA.view(), s.boxB.view()};
    writeCutVdb(dir.file("cut.vdb"), s.volume, *s.carved, *s.mask, fragments, s.info, {}, &recorder);
    EXPECT_EQ(recorder.phases, std::vector<std::string>{"level sets of the fragments"});
    ASSERT_FALSE(recorder.percents.empty());
    EXPECT_TRUE(std::is_sorted(recorder.percents.begin(), recorder.percents.end()))
        << ::testing::PrintToString(recorder.percents);
    EXPECT_EQ(recorder.percents.back(), 100);
    // 0, then one report per fragment (25, 50, 75, 100 in the order they finish).
    EXPECT_EQ(recorder.percents, (std::vector<int>{0, 25, 50, 75, 100}));
}

TEST(SliceExr, PartsChannelsValuesAndAttributesReadBack)
{
    const Scene s;
    test::TempDir dir;
    const std::string path = dir.file("slices.exr");
    Volume carvedVolume = s.volume;
    carvedVolume.grid = s.carved;
    writeSliceStack(path, carvedVolume, *s.mask, 300.0f);
    EXPECT_EQ(filesIn(dir.path()), std::vector<std::string>{"slices.exr"});

    Imf::MultiPartInputFile in(path.c_str());
    ASSERT_EQ(in.parts(), 40);
    auto ref = s.carved->getConstAccessor();
    std::vector<float> density(40 * 40);
    std::vector<uint32_t> mask(40 * 40);
    size_t maskVoxels = 0;
    for (int k = 0; k < 40; ++k) {
        const Imf::Header& h = in.header(k);
        ASSERT_EQ(h.name(), sliceName(k));
        EXPECT_EQ(h.type(), Imf::SCANLINEIMAGE);
        EXPECT_EQ(h.compression(), Imf::ZIP_COMPRESSION);
        EXPECT_EQ(h.dataWindow(), Imath::Box2i(Imath::V2i(0, 0), Imath::V2i(39, 39)));
        EXPECT_EQ(h.displayWindow(), h.dataWindow());
        EXPECT_EQ(h.pixelAspectRatio(), 1.0f);
        std::vector<std::string> channels;
        for (auto c = h.channels().begin(); c != h.channels().end(); ++c) channels.push_back(c.name());
        EXPECT_EQ(channels, (std::vector<std::string>{"density", "mask"}));
        EXPECT_EQ(h.channels().findChannel("density")->type, Imf::FLOAT);
        EXPECT_EQ(h.channels().findChannel("mask")->type, Imf::UINT);
        EXPECT_EQ(h.typedAttribute<Imf::V3dAttribute>("mtcut:spacing_mm").value(), Imath::V3d(0.5, 0.5, 1.0));
        EXPECT_EQ(h.typedAttribute<Imf::V3dAttribute>("mtcut:origin_mm").value(), Imath::V3d(-10, -10, -20));
        EXPECT_EQ(h.typedAttribute<Imf::IntAttribute>("mtcut:slice_index").value(), k);
        EXPECT_EQ(h.typedAttribute<Imf::DoubleAttribute>("mtcut:slice_z_mm").value(), -20.0 + k);
        EXPECT_EQ(h.typedAttribute<Imf::FloatAttribute>("mtcut:isovalue").value(), 300.0f);
        EXPECT_EQ(h.typedAttribute<Imf::StringAttribute>("mtcut:units").value(), "HU");
        EXPECT_EQ(h.typedAttribute<Imf::StringAttribute>("mtcut:version").value(), kMtcutVersion);

        Imf::InputPart part(in, k);
        Imf::FrameBuffer fb;
        fb.insert("density", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(density.data()), sizeof(float),
                                        40 * sizeof(float)));
        fb.insert("mask", Imf::Slice(Imf::UINT, reinterpret_cast<char*>(mask.data()), sizeof(uint32_t),
                                     40 * sizeof(uint32_t)));
        part.setFrameBuffer(fb);
        part.readPixels(0, 39);
        for (int j = 0; j < 40; ++j)
            for (int i = 0; i < 40; ++i) {
                const Coord c(i, j, k);
                ASSERT_EQ(density[size_t(i + 40 * j)], ref.getValue(c)) << c; // every voxel, bit-exact
                const auto m = kMaskVoxels.find(c);
                ASSERT_EQ(mask[size_t(i + 40 * j)], m == kMaskVoxels.end() ? 0u : uint32_t(m->second)) << c;
                maskVoxels += mask[size_t(i + 40 * j)] != 0;
            }
    }
    EXPECT_EQ(maskVoxels, kMaskVoxels.size());
    // Spot values: carved slab, kept ball, air.
    EXPECT_EQ(ref.getValue(Coord(20, 20, 20)), kAir);
    EXPECT_EQ(ref.getValue(Coord(16, 20, 20)), 1021.0f);
}

// setExrThreadCount sizes OpenEXR's global pool (the front ends give it every
// core), and the file it writes is the same, byte for byte, on any number of
// threads.
TEST(SliceExr, ThreadCountSizesOpenExrsPoolAndKeepsTheBytes)
{
    const Scene s;
    test::TempDir dir;
    Volume carvedVolume = s.volume;
    carvedVolume.grid = s.carved;
    auto bytes = [](const std::string& path) {
        std::ifstream in(path, std::ios::binary);
        return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    };
    const int before = Imf::globalThreadCount();
    setExrThreadCount(0);
    EXPECT_EQ(Imf::globalThreadCount(), 0);
    writeSliceStack(dir.file("serial.exr"), carvedVolume, *s.mask, 300.0f);
    setExrThreadCount(4);
    EXPECT_EQ(Imf::globalThreadCount(), 4);
    writeSliceStack(dir.file("threads.exr"), carvedVolume, *s.mask, 300.0f);
    Imf::setGlobalThreadCount(before);
    const std::string a = bytes(dir.file("serial.exr")), b = bytes(dir.file("threads.exr"));
    EXPECT_GT(a.size(), 1000u);
    EXPECT_TRUE(a == b) << "the threaded file differs (" << a.size() << " vs " << b.size() << " bytes)";
}

TEST(SliceExr, AnisotropicPixelsAndBadInput)
{
    DenseScan scan;
    scan.geometry.dims = Coord(6, 4, 3);
    scan.geometry.spacing = openvdb::Vec3d(0.5, 0.25, 2.0);
    scan.values.assign(6 * 4 * 3, 7.0f);
    const Volume volume = makeVolume(std::move(scan), "flat");
    test::TempDir dir;
    writeSliceStack(dir.file("s.exr"), volume, *openvdb::Int32Grid::create(0), 1.0f);
    {
        Imf::MultiPartInputFile in(dir.file("s.exr").c_str());
        ASSERT_EQ(in.parts(), 3);
        EXPECT_EQ(in.header(2).dataWindow(), Imath::Box2i(Imath::V2i(0, 0), Imath::V2i(5, 3)));
        EXPECT_EQ(in.header(2).pixelAspectRatio(), 2.0f);
        EXPECT_EQ(in.header(2).typedAttribute<Imf::DoubleAttribute>("mtcut:slice_z_mm").value(), 4.0);
    }

    auto zero = openvdb::Int32Grid::create(0);
    zero->tree().setValueOn(Coord(1, 2, 1), 0);
    try {
        writeSliceStack(dir.file("bad.exr"), volume, *zero, 1.0f);
        ADD_FAILURE() << "no error";
    } catch (const InputError& e) {
        EXPECT_EQ(std::string(e.what()), "cut mask voxel (1,2,1) has stroke id 0; stroke ids start at 1");
    }
    const std::string unwritable = dir.file("s.exr") + "/slices.exr"; // parent is a file
    try {
        writeSliceStack(unwritable, volume, *openvdb::Int32Grid::create(0), 1.0f);
        ADD_FAILURE() << "no error";
    } catch (const InputError& e) {
        EXPECT_EQ(std::string(e.what()).rfind(unwritable + ": cannot write EXR (", 0), 0u) << e.what();
    }
    StopAfter stop(2);
    EXPECT_THROW(writeSliceStack(dir.file("cancelled.exr"), volume, *openvdb::Int32Grid::create(0), 1.0f, &stop),
                 Cancelled);
    EXPECT_EQ(filesIn(dir.path()), std::vector<std::string>{"s.exr"});
}
