// File formats: NRRD, NIfTI, MetaImage, raw. Real files from ../shared/data
// (skipped when absent), exact round trips through every writer, orientation
// canonicalisation, and bad input fed on purpose (each must throw InputError
// naming the file, never crash or allocate what the header claims).
#include "tests/TestUtil.h"

#include "vdb/Error.h"
#include "vdb/Formats.h"
#include "vdb/HeaderParsers.h"
#include "vdb/VolumeIO.h"

#include <zlib.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

namespace fs = std::filesystem;
using namespace mtcut;
using namespace mtcut::vdb;
using mtcut::test::TempDir;

namespace {

void writeFile(const std::string& path, const std::string& bytes)
{
    std::ofstream out(path, std::ios::binary);
    out.write(bytes.data(), std::streamsize(bytes.size()));
    ASSERT_TRUE(bool(out)) << path;
}

template <typename T>
std::string bytesOf(const std::vector<T>& v, bool bigEndian = false)
{
    std::string s(v.size() * sizeof(T), '\0');
    std::memcpy(s.data(), v.data(), s.size());
    if (bigEndian) {
        for (size_t i = 0; i < v.size(); ++i) std::reverse(s.begin() + long(i * sizeof(T)), s.begin() + long((i + 1) * sizeof(T)));
    }
    return s;
}

std::string num(double v)
{
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.17g", v);
    return buf;
}

/// A small CT-like scan: air around a soft-tissue ellipsoid with a bone shell,
/// values -1000..1900, non-trivial spacing and origin.
DenseScan syntheticScan(int nx = 21, int ny = 17, int nz = 13)
{
    DenseScan s;
    s.geometry.dims = openvdb::Coord(nx, ny, nz);
    s.geometry.spacing = openvdb::Vec3d(0.5, 0.75, 1.25);
    s.geometry.origin = openvdb::Vec3d(-12.3, 45.6, 7.89);
    s.values.resize(size_t(nx) * ny * nz);
    for (int k = 0; k < nz; ++k) {
        for (int j = 0; j < ny; ++j) {
            for (int i = 0; i < nx; ++i) {
                const double x = (i - nx / 2.0) / (nx / 2.0), y = (j - ny / 2.0) / (ny / 2.0),
                             z = (k - nz / 2.0) / (nz / 2.0);
                const double r = std::sqrt(x * x + y * y + z * z);
                float v = -1000.0f;
                if (r < 0.9) v = 40.0f + float((i * 7 + j * 3 + k) % 50);
                if (r > 0.7 && r < 0.9) v = 700.0f + float((i + 2 * j + 3 * k) % 1200);
                s.values[size_t(i) + size_t(nx) * (size_t(j) + size_t(ny) * size_t(k))] = v;
            }
        }
    }
    return s;
}

void expectSameDense(const Volume& a, const Volume& b)
{
    ASSERT_EQ(a.dims, b.dims);
    EXPECT_EQ(a.spacing(), b.spacing());
    EXPECT_EQ(a.origin(), b.origin());
    const DenseScan da = toDense(a), db = toDense(b);
    ASSERT_EQ(da.values.size(), db.values.size());
    size_t differ = 0;
    for (size_t n = 0; n < da.values.size(); ++n) differ += da.values[n] != db.values[n];
    EXPECT_EQ(differ, 0u);
}

/// Runs f, expects an InputError whose one-line message names file and
/// contains what.
template <typename F>
void expectInputError(F&& f, const std::string& file, const std::string& what = "")
{
    try {
        f();
        ADD_FAILURE() << "no InputError for " << file;
    } catch (const InputError& e) {
        const std::string msg = e.what();
        EXPECT_NE(msg.find(file), std::string::npos) << msg;
        EXPECT_NE(msg.find(what), std::string::npos) << "'" << what << "' not in: " << msg;
        EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    } catch (const std::exception& e) {
        ADD_FAILURE() << "not an InputError: " << e.what();
    }
}

std::string nrrdHeader(const std::string& dims, const std::string& type, const std::string& extra = "")
{
    return "NRRD0004\ntype: " + type + "\ndimension: 3\nsizes: " + dims + "\n" + extra +
           "endian: little\nencoding: raw\n\n";
}

/// Minimal NIfTI-1 single file (.nii): header, 4 zero extension bytes, data.
std::string nifti1(const std::array<int16_t, 8>& dim, int16_t datatype, int16_t bitpix, const std::string& data,
                   float slope = 0.0f, float inter = 0.0f, int16_t sformCode = 0, const float srow[12] = nullptr,
                   const std::array<float, 3>& pixdim = {1.0f, 1.0f, 1.0f})
{
    std::string h(352, '\0');
    auto put = [&](size_t off, const void* p, size_t n) { std::memcpy(&h[off], p, n); };
    const int32_t size = 348;
    put(0, &size, 4);
    put(40, dim.data(), 16);
    put(70, &datatype, 2);
    put(72, &bitpix, 2);
    const float pd[8] = {1.0f, pixdim[0], pixdim[1], pixdim[2], 1.0f, 1.0f, 1.0f, 1.0f};
    put(76, pd, 32);
    const float voxOffset = 352.0f;
    put(108, &voxOffset, 4);
    put(112, &slope, 4);
    put(116, &inter, 4);
    h[123] = 2; // mm
    put(254, &sformCode, 2);
    if (srow) put(280, srow, 48);
    put(344, "n+1", 4);
    return h + data;
}

} // namespace

// ------------------------------------------------------------------ real files

TEST(Formats, ToothNrrdDetachedBigEndian)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    EXPECT_EQ(detectFormat(path), Format::Nrrd);
    const DenseScan scan = readNrrd(path, nullptr);
    EXPECT_EQ(scan.geometry.dims, openvdb::Coord(103, 94, 161));
    EXPECT_EQ(scan.geometry.spacing, openvdb::Vec3d(1.0));
    auto at = [&](int i, int j, int k) { return scan.values[size_t(i) + 103 * (size_t(j) + 94 * size_t(k))]; };
    EXPECT_EQ(at(0, 0, 0), 379.0f);
    EXPECT_EQ(at(51, 47, 80), 783.0f);
    EXPECT_EQ(at(60, 30, 100), 815.0f);
    EXPECT_EQ(at(20, 70, 10), 414.0f);
    EXPECT_EQ(at(102, 93, 160), 379.0f);
    const Volume vol = readVolume(path);
    EXPECT_EQ(vol.dims, openvdb::Coord(103, 94, 161));
    EXPECT_EQ(vol.origin(), openvdb::Vec3d(0.0));
    EXPECT_EQ(vol.minValue, 0.0f);
    EXPECT_EQ(vol.maxValue, 1300.0f);
    EXPECT_EQ(vol.units, "");
}

void checkHead(const std::string& path, const openvdb::Coord& dims, double spacing, float maxValue)
{
    const Volume vol = readVolume(path);
    EXPECT_EQ(vol.dims, dims);
    EXPECT_EQ(vol.spacing(), openvdb::Vec3d(spacing));
    EXPECT_EQ(vol.origin(), openvdb::Vec3d(74.0, 134.0, 1000.0));
    EXPECT_EQ(vol.minValue, -1024.0f);
    EXPECT_EQ(vol.maxValue, maxValue);
    EXPECT_EQ(vol.units, "HU");
    // The vertex is at +z: the top slices hold skull (bone) and the head's
    // cross-section shrinks toward them; the bottom holds the neck and jaw.
    const DenseScan d = toDense(vol);
    const size_t slice = size_t(dims.x()) * size_t(dims.y());
    auto count = [&](int k, float above) {
        size_t n = 0;
        for (size_t v = 0; v < slice; ++v) n += d.values[size_t(k) * slice + v] > above;
        return n;
    };
    const int top = dims.z() - 1, mid = dims.z() / 2;
    EXPECT_GT(count(top, 300.0f), 0u);
    EXPECT_GT(count(top - 2, 300.0f), 0u);
    EXPECT_LT(count(top, -500.0f), count(mid, -500.0f));
    EXPECT_LT(count(top - 2, -500.0f), count(mid, -500.0f));
}

TEST(Formats, VisibleHumanHeadNrrdGzip)
{
    MTCUT_REQUIRE_DATA(p2, "vhm_head_2mm.nhdr");
    MTCUT_REQUIRE_DATA(p4, "vhm_head_4mm.nhdr");
    checkHead(p2, openvdb::Coord(192, 176, 122), 2.0, 3264.0f);
    checkHead(p4, openvdb::Coord(96, 88, 61), 4.0, 3118.0f);
    const DenseScan s4 = readNrrd(p4, nullptr);
    EXPECT_EQ(s4.values[48 + 96 * (44 + 88 * 30)], 650.0f);
    EXPECT_EQ(s4.values[10 + 96 * (10 + 88 * 10)], -976.0f);
    const DenseScan s2 = readNrrd(p2, nullptr);
    EXPECT_EQ(s2.values[60 + 192 * (50 + 176 * 40)], -28.0f);
    EXPECT_EQ(s2.values[48 + 192 * (44 + 176 * 30)], -959.0f);
}

TEST(Formats, BodyCtNifti)
{
    MTCUT_REQUIRE_DATA(path, "body-ct.nii.gz");
    EXPECT_EQ(detectFormat(path), Format::Nifti);
    const DenseScan scan = readNifti(path, nullptr);
    const VolumeGeometry& g = scan.geometry;
    EXPECT_EQ(g.dims, openvdb::Coord(122, 101, 112));
    EXPECT_EQ(g.spacing, openvdb::Vec3d(3.0));
    // sform (code 2) in RAS -> LPS: x and y negated.
    EXPECT_EQ(g.origin, openvdb::Vec3d(177.95632934570312, -11.319000244140625, 94.3017578125));
    EXPECT_EQ(g.direction, openvdb::Mat3d(-1, 0, 0, 0, -1, 0, 0, 0, 1));
    auto at = [&](int i, int j, int k) { return scan.values[size_t(i) + 122 * (size_t(j) + 101 * size_t(k))]; };
    EXPECT_EQ(at(0, 0, 0), -1023.0f);
    EXPECT_EQ(at(61, 50, 56), 164.0f);
    EXPECT_EQ(at(30, 40, 50), -114.0f);
    EXPECT_EQ(at(100, 20, 90), -99.0f);
    EXPECT_EQ(at(121, 100, 111), -997.0f);

    const Volume vol = readVolume(path);
    EXPECT_EQ(vol.dims, openvdb::Coord(122, 101, 112));
    EXPECT_EQ(vol.units, "HU");
    // Canonical axes run along +x, +y: file voxel (i,j,k) is (121-i, 100-j, k).
    EXPECT_EQ(vol.origin(), openvdb::Vec3d(177.95632934570312 - 363.0, -11.319000244140625 - 300.0, 94.3017578125));
    const auto acc = vol.grid->getConstAccessor();
    EXPECT_EQ(acc.getValue(openvdb::Coord(121 - 61, 100 - 50, 56)), 164.0f);
    EXPECT_EQ(acc.getValue(openvdb::Coord(121 - 30, 100 - 40, 50)), -114.0f);
}

// ------------------------------------------------------------------ round trips

void roundTrip(const Volume& original, const TempDir& dir)
{
    for (const char* ext : {".vdb", ".nrrd", ".nhdr", ".mha", ".mhd", ".raw"}) {
        SCOPED_TRACE(ext);
        const std::string path = dir.file(std::string("rt_") + (ext + 1) + ext);
        writeVolume(original, path);
        ReadOptions options;
        if (std::string(ext) == ".raw") {
            const openvdb::Vec3d s = original.spacing(), o = original.origin();
            options.raw = parseRawOptions("dims=" + std::to_string(original.dims.x()) + "," +
                                          std::to_string(original.dims.y()) + "," + std::to_string(original.dims.z()) +
                                          " type=float32 endian=little spacing=" + num(s.x()) + "," + num(s.y()) + "," +
                                          num(s.z()) + " origin=" + num(o.x()) + "," + num(o.y()) + "," + num(o.z()));
        }
        const Volume back = readVolume(path, options);
        expectSameDense(original, back);
        EXPECT_EQ(back.units, original.units);
        EXPECT_EQ(back.minValue, original.minValue);
        EXPECT_EQ(back.maxValue, original.maxValue);
    }
    // Nothing but the outputs (and the detached data files) is left behind.
    size_t files = 0;
    for (const auto& e : fs::directory_iterator(dir.path())) {
        EXPECT_EQ(e.path().string().find(".tmp."), std::string::npos) << e.path();
        ++files;
    }
    EXPECT_EQ(files, 8u); // six outputs + the data files of .nhdr and .mhd
}

TEST(Formats, RoundTripSynthetic)
{
    TempDir dir;
    DenseScan scan = syntheticScan();
    const Volume original = makeVolume(std::move(scan), "synthetic");
    EXPECT_EQ(original.minValue, -1000.0f);
    roundTrip(original, dir);
}

TEST(Formats, RoundTripHead)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_4mm.nhdr");
    TempDir dir;
    roundTrip(readVolume(path), dir);
}

TEST(Formats, MetaImageCompressedBigEndianDetached)
{
    TempDir dir;
    const DenseScan scan = syntheticScan(9, 7, 5);
    std::vector<int16_t> v(scan.values.begin(), scan.values.end());
    const std::string raw = bytesOf(v, true);
    uLongf zlen = compressBound(uLong(raw.size()));
    std::string z(zlen, '\0');
    ASSERT_EQ(compress(reinterpret_cast<Bytef*>(z.data()), &zlen, reinterpret_cast<const Bytef*>(raw.data()),
                       uLong(raw.size())),
              Z_OK);
    z.resize(zlen);
    const std::string common = "ObjectType = Image\nNDims = 3\nDimSize = 9 7 5\nElementType = MET_SHORT\n"
                               "ElementSpacing = 0.5 0.75 1.25\nOffset = -12.3 45.6 7.89\n"
                               "ElementByteOrderMSB = True\n";
    writeFile(dir.file("c.mha"), common + "CompressedData = True\nCompressedDataSize = " + std::to_string(z.size()) +
                                     "\nElementDataFile = LOCAL\n" + z);
    writeFile(dir.file("d.dat"), std::string(100, 'x') + raw);
    writeFile(dir.file("d.mhd"), common + "HeaderSize = -1\nElementDataFile = d.dat\n");
    writeFile(dir.file("e.mhd"), common + "HeaderSize = 100\nElementDataFile = d.dat\n");
    for (const char* name : {"c.mha", "d.mhd", "e.mhd"}) {
        SCOPED_TRACE(name);
        const DenseScan got = readMetaImage(dir.file(name), nullptr);
        EXPECT_EQ(got.geometry.dims, openvdb::Coord(9, 7, 5));
        EXPECT_EQ(got.geometry.spacing, openvdb::Vec3d(0.5, 0.75, 1.25));
        EXPECT_EQ(got.geometry.origin, openvdb::Vec3d(-12.3, 45.6, 7.89));
        EXPECT_EQ(got.values, scan.values);
    }
}

TEST(Formats, NiftiScalingAndGeometryFallbacks)
{
    TempDir dir;
    const std::vector<int16_t> v = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11};
    // pixdim only: RAS index axes -> LPS directions (-1,-1,+1), slope/intercept applied.
    writeFile(dir.file("a.nii"), nifti1({3, 3, 2, 2, 1, 1, 1, 1}, 4, 16, bytesOf(v), 2.0f, -1024.0f, 0, nullptr,
                                        {0.5f, 0.25f, 2.0f}));
    DenseScan a = readNifti(dir.file("a.nii"), nullptr);
    EXPECT_EQ(a.geometry.dims, openvdb::Coord(3, 2, 2));
    EXPECT_EQ(a.geometry.spacing, openvdb::Vec3d(0.5, 0.25, 2.0));
    EXPECT_EQ(a.geometry.direction, openvdb::Mat3d(-1, 0, 0, 0, -1, 0, 0, 0, 1));
    EXPECT_EQ(a.values[0], -1024.0f);
    EXPECT_EQ(a.values[11], -1002.0f);
    // sform with a permutation: file i runs along RAS y, file j along RAS -x.
    const float srow[12] = {0, -2, 0, 10, 3, 0, 0, 20, 0, 0, 4, 30};
    writeFile(dir.file("b.nii"), nifti1({3, 3, 2, 2, 1, 1, 1, 1}, 4, 16, bytesOf(v), 0.0f, 5.0f, 1, srow));
    DenseScan b = readNifti(dir.file("b.nii"), nullptr);
    EXPECT_EQ(b.geometry.spacing, openvdb::Vec3d(3.0, 2.0, 4.0));
    EXPECT_EQ(b.geometry.origin, openvdb::Vec3d(-10.0, -20.0, 30.0));
    EXPECT_EQ(b.geometry.direction, openvdb::Mat3d(0, 1, 0, -1, 0, 0, 0, 0, 1));
    EXPECT_EQ(b.values[11], 11.0f); // slope 0: unscaled, intercept ignored
    // 4-D, nt = 2: the first volume is read.
    std::vector<int16_t> v4 = v;
    for (int16_t x : v) v4.push_back(int16_t(100 + x));
    writeFile(dir.file("c.nii"), nifti1({4, 3, 2, 2, 2, 1, 1, 1}, 4, 16, bytesOf(v4)));
    EXPECT_EQ(readNifti(dir.file("c.nii"), nullptr).values, std::vector<float>(v.begin(), v.end()));
}

// ------------------------------------------------------------------ orientation

TEST(Formats, NrrdFlipsAndPermutationsCanonicalise)
{
    TempDir dir;
    const DenseScan plain = syntheticScan(6, 5, 4);
    const int nx = 6, ny = 5, nz = 4;
    auto at = [&](int i, int j, int k) { return plain.values[size_t(i) + nx * (size_t(j) + ny * size_t(k))]; };
    const std::string origin = "(" + num(-12.3) + "," + num(45.6) + "," + num(7.89) + ")";
    writeFile(dir.file("plain.nrrd"),
              nrrdHeader("6 5 4", "float", "space: LPS\nspace directions: (0.5,0,0) (0,0.75,0) (0,0,1.25)\nspace origin: " + origin + "\n") +
                  bytesOf(plain.values));
    // x flipped: file i runs along -x from the last voxel.
    std::vector<float> flipped;
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = nx - 1; i >= 0; --i) flipped.push_back(at(i, j, k));
    writeFile(dir.file("flip.nrrd"),
              nrrdHeader("6 5 4", "float",
                         "space: LPS\nspace directions: (-0.5,0,0) (0,0.75,0) (0,0,1.25)\nspace origin: (" +
                             num(-12.3 + 0.5 * 5) + "," + num(45.6) + "," + num(7.89) + ")\n") +
                  bytesOf(flipped));
    // i and j swapped, and the same volume in RAS.
    std::vector<float> permuted;
    for (int k = 0; k < nz; ++k)
        for (int i = 0; i < nx; ++i)
            for (int j = 0; j < ny; ++j) permuted.push_back(at(i, j, k));
    writeFile(dir.file("perm.nrrd"),
              nrrdHeader("5 6 4", "float", "space: right-anterior-superior\nspace directions: (0,-0.75,0) (-0.5,0,0) (0,0,1.25)\nspace origin: (" +
                                               num(12.3) + "," + num(-45.6) + "," + num(7.89) + ")\n") +
                  bytesOf(permuted));
    const Volume a = readVolume(dir.file("plain.nrrd"));
    EXPECT_NEAR(a.origin().x(), -12.3, 1e-12);
    for (const char* name : {"flip.nrrd", "perm.nrrd"}) {
        SCOPED_TRACE(name);
        const Volume b = readVolume(dir.file(name));
        ASSERT_EQ(a.dims, b.dims);
        EXPECT_EQ(a.spacing(), b.spacing());
        EXPECT_NEAR((a.origin() - b.origin()).length(), 0.0, 1e-12);
        const DenseScan da = toDense(a), db = toDense(b);
        EXPECT_EQ(da.values, db.values);
    }
    // Oblique: rejected with a clear message.
    writeFile(dir.file("oblique.nrrd"),
              nrrdHeader("6 5 4", "float", "space: LPS\nspace directions: (0.5,0.1,0) (0,0.75,0) (0,0,1.25)\n") +
                  bytesOf(plain.values));
    expectInputError([&] { readVolume(dir.file("oblique.nrrd")); }, dir.file("oblique.nrrd"), "oblique");
}

// ------------------------------------------------------------------ bad input

TEST(FormatsBad, TruncatedData)
{
    TempDir dir;
    const std::vector<float> v(6 * 5 * 4, 1.0f);
    const std::string data = bytesOf(v);
    const std::string cut = data.substr(0, data.size() - 10);
    writeFile(dir.file("t.nrrd"), nrrdHeader("6 5 4", "float") + cut);
    expectInputError([&] { readVolume(dir.file("t.nrrd")); }, dir.file("t.nrrd"));
    writeFile(dir.file("t.mha"), "NDims = 3\nDimSize = 6 5 4\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n" + cut);
    expectInputError([&] { readVolume(dir.file("t.mha")); }, dir.file("t.mha"), "need");
    writeFile(dir.file("t.raw"), cut);
    ReadOptions o;
    o.raw = parseRawOptions("dims=6,5,4 type=float32");
    expectInputError([&] { readVolume(dir.file("t.raw"), o); }, dir.file("t.raw"), "file has 470 bytes");
    o.raw = parseRawOptions("dims=6,5,4 type=uint8 offset=400");
    expectInputError([&] { readVolume(dir.file("t.raw"), o); }, dir.file("t.raw"), "need 520 bytes");
    // A gzip stream cut short, attached and compressed MetaImage.
    uLongf zlen = compressBound(uLong(data.size()));
    std::string z(zlen, '\0');
    compress(reinterpret_cast<Bytef*>(z.data()), &zlen, reinterpret_cast<const Bytef*>(data.data()), uLong(data.size()));
    z.resize(zlen / 2);
    writeFile(dir.file("z.mha"), "NDims = 3\nDimSize = 6 5 4\nElementType = MET_FLOAT\nCompressedData = True\n"
                                 "ElementDataFile = LOCAL\n" + z);
    expectInputError([&] { readVolume(dir.file("z.mha")); }, dir.file("z.mha"));
}

TEST(FormatsBad, HeaderClaimsMoreThanFile)
{
    TempDir dir;
    // 512^3 int16 (256 MiB) claimed, 1 KiB present: rejected before teem allocates.
    writeFile(dir.file("big.nrrd"), nrrdHeader("512 512 512", "short") + std::string(1024, '\0'));
    expectInputError([&] { readVolume(dir.file("big.nrrd")); }, dir.file("big.nrrd"), "268435456 bytes");
    writeFile(dir.file("d.raw.gz"), std::string(64, 'x'));
    writeFile(dir.file("big.nhdr"), "NRRD0004\ntype: short\ndimension: 3\nsizes: 512 512 512\nencoding: gzip\n"
                                    "endian: little\ndata file: d.raw.gz\n");
    expectInputError([&] { readVolume(dir.file("big.nhdr")); }, dir.file("big.nhdr"), "truncated");
    // A real gzip stream shorter than the header says: teem's own complaint, one line.
    std::string gz;
    {
        const std::string file = dir.file("small.gz");
        gzFile f = gzopen(file.c_str(), "wb");
        const std::vector<int16_t> v(1000, 7);
        gzwrite(f, v.data(), unsigned(v.size() * 2));
        gzclose(f);
    }
    writeFile(dir.file("short.nhdr"), "NRRD0004\ntype: short\ndimension: 3\nsizes: 20 20 20\nencoding: gzip\n"
                                      "endian: little\ndata file: small.gz\n");
    expectInputError([&] { readVolume(dir.file("short.nhdr")); }, dir.file("short.nhdr"));
    writeFile(dir.file("big.mha"), "NDims = 3\nDimSize = 512 512 512\nElementType = MET_SHORT\nCompressedData = True\n"
                                   "ElementDataFile = LOCAL\n" + std::string(100, 'x'));
    expectInputError([&] { readVolume(dir.file("big.mha")); }, dir.file("big.mha"), "cannot hold");
    // NIfTI claiming 512^3 with 100 bytes of data.
    writeFile(dir.file("big.nii"), nifti1({3, 512, 512, 512, 1, 1, 1, 1}, 4, 16, std::string(100, '\0')));
    expectInputError([&] { readVolume(dir.file("big.nii")); }, dir.file("big.nii"));
}

TEST(FormatsBad, HugeDimensionsRejectedBeforeAllocating)
{
    TempDir dir;
    writeFile(dir.file("huge.nrrd"), nrrdHeader("100000 100000 100000", "float"));
    expectInputError([&] { readVolume(dir.file("huge.nrrd")); }, dir.file("huge.nrrd"), "limit");
    writeFile(dir.file("huge2.nrrd"), nrrdHeader("60000 60000 60000", "uchar"));
    expectInputError([&] { readVolume(dir.file("huge2.nrrd")); }, dir.file("huge2.nrrd"), "limit");
    writeFile(dir.file("huge.mha"), "NDims = 3\nDimSize = 100000 100000 100000\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n");
    expectInputError([&] { readVolume(dir.file("huge.mha")); }, dir.file("huge.mha"), "limit");
    writeFile(dir.file("huge.raw"), "x");
    ReadOptions o;
    EXPECT_THROW(parseRawOptions("dims=100000,100000,100000 type=float32"), InputError);
    o.raw = parseRawOptions("dims=65536,65536,65536 type=float32");
    expectInputError([&] { readVolume(dir.file("huge.raw"), o); }, dir.file("huge.raw"), "limit");
    writeFile(dir.file("huge.nii"), nifti1({3, 32000, 32000, 32000, 1, 1, 1, 1}, 16, 32, ""));
    expectInputError([&] { readVolume(dir.file("huge.nii")); }, dir.file("huge.nii"), "limit");
}

TEST(FormatsBad, ZeroAndNegativeSizes)
{
    TempDir dir;
    writeFile(dir.file("zero.nrrd"), nrrdHeader("6 0 4", "float"));
    expectInputError([&] { readVolume(dir.file("zero.nrrd")); }, dir.file("zero.nrrd"));
    writeFile(dir.file("neg.nrrd"), nrrdHeader("6 -5 4", "float"));
    expectInputError([&] { readVolume(dir.file("neg.nrrd")); }, dir.file("neg.nrrd"));
    writeFile(dir.file("zero.mha"), "NDims = 3\nDimSize = 6 0 4\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n");
    expectInputError([&] { readVolume(dir.file("zero.mha")); }, dir.file("zero.mha"), "positive");
    writeFile(dir.file("neg.mha"), "NDims = 3\nDimSize = 6 -5 4\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n");
    expectInputError([&] { readVolume(dir.file("neg.mha")); }, dir.file("neg.mha"), "positive");
    writeFile(dir.file("zero.nii"), nifti1({3, 6, 0, 4, 1, 1, 1, 1}, 16, 32, ""));
    expectInputError([&] { readVolume(dir.file("zero.nii")); }, dir.file("zero.nii"));
    writeFile(dir.file("neg.nii"), nifti1({3, 6, -5, 4, 1, 1, 1, 1}, 16, 32, ""));
    expectInputError([&] { readVolume(dir.file("neg.nii")); }, dir.file("neg.nii"));
    expectInputError([] { parseRawOptions("dims=6,0,4 type=int16"); }, "dims=6,0,4", "positive");
    expectInputError([] { parseRawOptions("dims=6,-5,4 type=int16"); }, "dims=6,-5,4", "positive");
    writeFile(dir.file("zs.mha"), "NDims = 3\nDimSize = 6 5 4\nElementSpacing = 1 0 1\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n");
    expectInputError([&] { readVolume(dir.file("zs.mha")); }, dir.file("zs.mha"), "ElementSpacing");
}

TEST(FormatsBad, UnsupportedTypes)
{
    TempDir dir;
    writeFile(dir.file("ll.nrrd"), nrrdHeader("2 2 2", "int64") + std::string(64, '\0'));
    expectInputError([&] { readVolume(dir.file("ll.nrrd")); }, dir.file("ll.nrrd"), "not supported");
    writeFile(dir.file("rgb.nrrd"), "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 3 2 2 2\nencoding: raw\n\n" + std::string(24, '\0'));
    expectInputError([&] { readVolume(dir.file("rgb.nrrd")); }, dir.file("rgb.nrrd"), "3-D");
    writeFile(dir.file("ll.mha"), "NDims = 3\nDimSize = 2 2 2\nElementType = MET_LONG_LONG\nElementDataFile = LOCAL\n" + std::string(64, '\0'));
    expectInputError([&] { readVolume(dir.file("ll.mha")); }, dir.file("ll.mha"), "ElementType");
    writeFile(dir.file("rgb.mha"), "NDims = 3\nDimSize = 2 2 2\nElementNumberOfChannels = 3\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n" + std::string(24, '\0'));
    expectInputError([&] { readVolume(dir.file("rgb.mha")); }, dir.file("rgb.mha"), "single-channel");
    writeFile(dir.file("c.nii"), nifti1({3, 2, 2, 2, 1, 1, 1, 1}, 32, 64, std::string(64, '\0'))); // complex64
    expectInputError([&] { readVolume(dir.file("c.nii")); }, dir.file("c.nii"), "not supported");
    writeFile(dir.file("rgb.nii"), nifti1({3, 2, 2, 2, 1, 1, 1, 1}, 128, 24, std::string(24, '\0'))); // RGB24
    expectInputError([&] { readVolume(dir.file("rgb.nii")); }, dir.file("rgb.nii"), "not supported");
    expectInputError([] { parseRawOptions("dims=2,2,2 type=complex64"); }, "type=complex64", "unsupported");
}

TEST(FormatsBad, NaNValuesRejected)
{
    TempDir dir;
    std::vector<float> v(4 * 4 * 4, 100.0f);
    v[21] = std::numeric_limits<float>::quiet_NaN();
    writeFile(dir.file("nan.raw"), bytesOf(v));
    ReadOptions o;
    o.raw = parseRawOptions("dims=4,4,4 type=float32");
    expectInputError([&] { readVolume(dir.file("nan.raw"), o); }, dir.file("nan.raw"));
    writeFile(dir.file("nan.mha"), "NDims = 3\nDimSize = 4 4 4\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n" + bytesOf(v));
    expectInputError([&] { readVolume(dir.file("nan.mha")); }, dir.file("nan.mha"));
    writeFile(dir.file("nan.nrrd"), nrrdHeader("4 4 4", "float") + bytesOf(v));
    expectInputError([&] { readVolume(dir.file("nan.nrrd")); }, dir.file("nan.nrrd"));
}

TEST(FormatsBad, GarbageHeaders)
{
    TempDir dir;
    writeFile(dir.file("g.nrrd"), "NRRD0004\nthis is not a field\nsizes: banana\n\n");
    expectInputError([&] { readVolume(dir.file("g.nrrd")); }, dir.file("g.nrrd"));
    writeFile(dir.file("g.mha"), "NDims = 3\nDimSize 6 5 4\nElementDataFile = LOCAL\n");
    expectInputError([&] { readVolume(dir.file("g.mha")); }, dir.file("g.mha"), "line 2");
    writeFile(dir.file("g2.mha"), "NDims = 3\nDimSize = 6 five 4\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n");
    expectInputError([&] { readVolume(dir.file("g2.mha")); }, dir.file("g2.mha"), "DimSize");
    writeFile(dir.file("g3.mha"), std::string("NDims = 3\nDimSize = 6 5 4\n\x01\x02garbage"));
    expectInputError([&] { readVolume(dir.file("g3.mha")); }, dir.file("g3.mha"), "line 3");
    writeFile(dir.file("g.nii"), std::string(400, 'z'));
    expectInputError([&] { readVolume(dir.file("g.nii")); }, dir.file("g.nii"), "unknown format");
    std::string broken = nifti1({3, 2, 2, 2, 1, 1, 1, 1}, 4, 16, std::string(16, '\0'));
    broken[40] = 9; // ndim 9
    writeFile(dir.file("g2.nii"), broken);
    expectInputError([&] { readVolume(dir.file("g2.nii")); }, dir.file("g2.nii"));
}

TEST(FormatsBad, MissingDetachedDataFile)
{
    TempDir dir;
    writeFile(dir.file("m.nhdr"), "NRRD0004\ntype: short\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
                                  "endian: little\ndata file: gone.raw\n");
    expectInputError([&] { readVolume(dir.file("m.nhdr")); }, dir.file("m.nhdr"));
    writeFile(dir.file("m.mhd"), "NDims = 3\nDimSize = 2 2 2\nElementType = MET_SHORT\nElementDataFile = gone.raw\n");
    expectInputError([&] { readVolume(dir.file("m.mhd")); }, dir.file("m.mhd"), "gone.raw");
}

TEST(FormatsBad, RawOptionsNameTheKey)
{
    const RawOptions ok = parseRawOptions("  dims=512,512,245\ttype=short endian=big spacing=0.5 origin=-1,2.5,3e2 offset=128 ");
    EXPECT_EQ(ok.dims, (std::array<int, 3>{512, 512, 245}));
    EXPECT_EQ(ok.type, "int16");
    EXPECT_TRUE(ok.bigEndian);
    EXPECT_EQ(ok.spacing, (std::array<double, 3>{0.5, 0.5, 0.5}));
    EXPECT_EQ(ok.origin, (std::array<double, 3>{-1.0, 2.5, 300.0}));
    EXPECT_EQ(ok.headerBytes, 128u);
    const std::pair<const char*, const char*> bad[] = {
        {"dims=1,2 type=int16", "dims"},
        {"dims=1,2,3,4 type=int16", "dims"},
        {"dims=1,2,3x type=int16", "dims"},
        {"dims=1,,3 type=int16", "dims"},
        {"dims=99999999999999999999,2,3 type=int16", "dims"},
        {"dims=1,2,3 type=int16 spacing=1,nan,1", "spacing"},
        {"dims=1,2,3 type=int16 spacing=1,-1,1", "spacing"},
        {"dims=1,2,3 type=int16 spacing=1e999", "spacing"},
        {"dims=1,2,3 type=int16 origin=0,0,inf", "origin"},
        {"dims=1,2,3 type=int16 offset=-1", "offset"},
        {"dims=1,2,3 type=int16 offset=99999999999999999999999", "offset"},
        {"dims=1,2,3 type=int16 endian=middle", "endian"},
        {"dims=1,2,3 type=int16 colour=red", "colour"},
        {"dims=1,2,3 type=int16 type=int8", "type"},
        {"dims=1,2,3 type=", "type"},
        {"dims=1,2,3", "type"},
        {"type=int16", "dims"},
    };
    for (const auto& [spec, key] : bad) expectInputError([&] { parseRawOptions(spec); }, key);
}

TEST(FormatsCli, BadInputIsOneLineAndLeavesNoOutput)
{
    TempDir dir;
    const std::vector<float> v(6 * 5 * 4, 1.0f);
    const std::string bad = dir.file("bad.nrrd");
    writeFile(bad, nrrdHeader("6 5 4", "float") + bytesOf(v).substr(0, 100));
    for (const char* out : {"out.vdb", "out.nrrd", "out.nhdr", "out.mhd"}) {
        const auto r = mtcut::test::runMtcut("convert '" + bad + "' '" + dir.file(out) + "'");
        EXPECT_EQ(r.exitCode, 1) << r.output;
        EXPECT_EQ(r.output.rfind("mtcut: error: ", 0), 0u) << r.output;
        EXPECT_NE(r.output.find(bad), std::string::npos) << r.output;
        EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    }
    const auto r = mtcut::test::runMtcut("info '" + dir.file("bad.raw") + "' --dims 6,5,4 --type int16");
    EXPECT_EQ(r.exitCode, 1);
    EXPECT_EQ(r.output.rfind("mtcut: error: ", 0), 0u) << r.output;
    // Only the bad input is left in the folder: no output, no temporary file.
    std::vector<std::string> left;
    for (const auto& e : fs::directory_iterator(dir.path())) left.push_back(e.path().filename().string());
    EXPECT_EQ(left, std::vector<std::string>{"bad.nrrd"});
}
