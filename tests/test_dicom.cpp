// DICOM series reading (vdb/DicomReader.cpp): real series (the VHM head,
// a JPEG 2000 body CT) and small synthetic series written here with GDCM,
// which check sorting by position, rescale, series choice and bad input.
#include "tests/TestUtil.h"
#include "vdb/Formats.h"
#include "vdb/VolumeIO.h"

// GDCM's include folder is private to mtcut_vdb; its headers include each other with quotes.
#include <gdcm-3.0/gdcmAttribute.h>
#include <gdcm-3.0/gdcmImageWriter.h>
#include <gdcm-3.0/gdcmMediaStorage.h>
#include <gdcm-3.0/gdcmTrace.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <set>

namespace mtcut {
namespace {

using openvdb::Coord;
using openvdb::Vec3d;

float voxel(const vdb::Volume& vol, int i, int j, int k)
{
    return vol.grid->getConstAccessor().getValue(Coord(i, j, k));
}

// ---------------------------------------------------------------------------
// Synthetic series

/// A small CT series on an axis-aligned grid. In canonical index space (x, y,
/// z growing) voxel (i,j,k) stores storedValue(i,j,k) and reads back as
/// 2 * stored - 1024 HU (slope 2, intercept -1024).
struct Series
{
    int columns = 16;
    int rows = 12;
    int slices = 10;
    double columnSpacing = 0.5; ///< mm along a row (x)
    double rowSpacing = 0.75;   ///< mm down a column (y)
    double step = 2.0;          ///< mm between slices
    Vec3d corner{-10.0, 20.0, 50.0}; ///< world mm of canonical voxel (0,0,0)
    bool flipped = false;       ///< column direction -y and normal -z (instead of +y, +z)
    std::string uid = "1.2.826.0.1.3680043.9.7.1.1";
    int offset = 0; ///< added to every stored value (tells series apart)
    double shear = 0.0; ///< mm added to x per slice (a gantry tilt)

    int storedValue(int i, int j, int k) const { return 300 + i + 20 * j + 300 * k + offset; }
    float hu(int i, int j, int k) const { return float(2 * storedValue(i, j, k) - 1024); }

    /// Writes slice s (s-th along the slice normal) to path; columnsOverride
    /// makes a slice of another size.
    void writeSlice(const std::string& path, int s, int columnsOverride = 0) const
    {
        const int cols = columnsOverride > 0 ? columnsOverride : columns;
        const Vec3d rowDir(1, 0, 0);
        const Vec3d colDir(0, flipped ? -1 : 1, 0);
        const Vec3d normal = rowDir.cross(colDir);
        const Vec3d first = flipped ? corner + Vec3d(0, (rows - 1) * rowSpacing, (slices - 1) * step) : corner;
        const Vec3d ipp = first + normal * (s * step) + Vec3d(shear * s, 0, 0);

        std::vector<int16_t> pixels(size_t(cols) * size_t(rows));
        for (int r = 0; r < rows; ++r) {
            for (int c = 0; c < cols; ++c) {
                const Vec3d world = ipp + rowDir * (c * columnSpacing) + colDir * (r * rowSpacing);
                const Vec3d ijk = (world - corner) / Vec3d(columnSpacing, rowSpacing, step);
                pixels[size_t(r) * size_t(cols) + size_t(c)] = int16_t(
                    storedValue(int(std::lround(ijk.x())), int(std::lround(ijk.y())), int(std::lround(ijk.z()))));
            }
        }

        gdcm::Trace::WarningOff(); // the writer's notes about tags it fills in itself
        gdcm::ImageWriter writer;
        gdcm::Image& image = writer.GetImage();
        image.SetNumberOfDimensions(2);
        image.SetDimension(0, unsigned(cols));
        image.SetDimension(1, unsigned(rows));
        image.SetPixelFormat(gdcm::PixelFormat(gdcm::PixelFormat::INT16));
        image.SetPhotometricInterpretation(gdcm::PhotometricInterpretation::MONOCHROME2);
        image.SetSpacing(0, columnSpacing);
        image.SetSpacing(1, rowSpacing);
        const double origin[3] = {ipp.x(), ipp.y(), ipp.z()};
        image.SetOrigin(origin);
        image.SetOrigin(2, ipp.z()); // SetOrigin(double*) keeps only NumberOfDimensions (2) values
        const double cosines[6] = {rowDir.x(), rowDir.y(), rowDir.z(), colDir.x(), colDir.y(), colDir.z()};
        image.SetDirectionCosines(cosines);
        image.SetSlope(2.0);
        image.SetIntercept(-1024.0);
        gdcm::DataElement data(gdcm::Tag(0x7fe0, 0x0010));
        data.SetByteValue(reinterpret_cast<const char*>(pixels.data()), uint32_t(pixels.size() * sizeof(int16_t)));
        image.SetDataElement(data);

        gdcm::DataSet& ds = writer.GetFile().GetDataSet();
        gdcm::Attribute<0x0008, 0x0016> sopClass;
        sopClass.SetValue(gdcm::MediaStorage::GetMSString(gdcm::MediaStorage::CTImageStorage));
        ds.Replace(sopClass.GetAsDataElement());
        gdcm::Attribute<0x0008, 0x0060> modality;
        modality.SetValue("CT");
        ds.Replace(modality.GetAsDataElement());
        gdcm::Attribute<0x0020, 0x000e> series;
        series.SetValue(uid);
        ds.Replace(series.GetAsDataElement());
        gdcm::Attribute<0x0020, 0x0013> instance; // deliberately against position order
        instance.SetValue(slices - s);
        ds.Replace(instance.GetAsDataElement());

        writer.SetFileName(path.c_str());
        if (!writer.Write()) throw std::runtime_error("test: cannot write " + path);
    }

    /// Writes all slices into dir with names whose order is not position order
    /// (a flipped series has decreasing z in slice order).
    void write(const std::string& dir, const std::string& prefix = "IM", std::set<int> skip = {}) const
    {
        for (int s = 0; s < slices; ++s) {
            if (skip.count(s)) continue;
            writeSlice(dir + "/" + fileName(prefix, s), s);
        }
    }

    /// Files are numbered in a shuffled order: slice s goes to number (7 s + 3) mod 10 (+10 per ten).
    std::string fileName(const std::string& prefix, int s) const
    {
        char name[64];
        std::snprintf(name, sizeof(name), "%s%04d.dcm", prefix.c_str(), (s / 10) * 10 + (7 * (s % 10) + 3) % 10);
        return name;
    }
};

void writeText(const std::string& path, const std::string& text)
{
    std::ofstream(path, std::ios::binary) << text;
}

void writeFakePng(const std::string& path)
{
    std::string bytes("\x89PNG\r\n\x1a\n", 8);
    for (int i = 0; i < 4000; ++i) bytes.push_back(char((i * 37 + 11) & 0xff));
    writeText(path, bytes);
}

/// Runs readVolume and returns the InputError's message ("" when it did not throw one).
std::string readError(const std::string& path, const vdb::ReadOptions& options = {})
{
    try {
        vdb::readVolume(path, options);
    } catch (const InputError& e) {
        const std::string message = e.what();
        EXPECT_EQ(message.find('\n'), std::string::npos) << "error must be one line: " << message;
        return message;
    }
    ADD_FAILURE() << path << ": expected an InputError";
    return {};
}

void expectValues(const vdb::Volume& vol, const Series& series)
{
    ASSERT_EQ(vol.dims, Coord(series.columns, series.rows, series.slices));
    int mismatches = 0;
    for (int k = 0; k < series.slices; ++k) {
        for (int j = 0; j < series.rows; ++j) {
            for (int i = 0; i < series.columns; ++i) {
                if (voxel(vol, i, j, k) != series.hu(i, j, k) && mismatches++ < 5) {
                    ADD_FAILURE() << "voxel " << i << "," << j << "," << k << ": " << voxel(vol, i, j, k)
                                  << ", expected " << series.hu(i, j, k);
                }
            }
        }
    }
    EXPECT_EQ(mismatches, 0);
}

TEST(DicomSynthetic, ShuffledNamesSortByPosition)
{
    test::TempDir dir;
    Series series;
    series.write(dir.path());
    // File-name order differs from position order: IM0003 is slice 0, IM0000 is slice 1.
    ASSERT_EQ(series.fileName("IM", 0), "IM0003.dcm");
    ASSERT_EQ(series.fileName("IM", 1), "IM0000.dcm");

    const vdb::DenseScan scan = vdb::readDicomSeries(dir.path(), {}, nullptr);
    EXPECT_EQ(scan.geometry.dims, Coord(16, 12, 10));
    EXPECT_EQ(scan.geometry.spacing, Vec3d(0.5, 0.75, 2.0));
    EXPECT_EQ(scan.geometry.origin, series.corner);
    EXPECT_EQ(scan.geometry.direction, openvdb::Mat3d::identity());
    EXPECT_EQ(scan.units, "HU");
    ASSERT_EQ(scan.values.size(), size_t(16 * 12 * 10));
    EXPECT_EQ(scan.values[0], series.hu(0, 0, 0));
    EXPECT_EQ(scan.values[5 + 16 * (7 + 12 * 9)], series.hu(5, 7, 9));

    const vdb::Volume vol = vdb::readVolume(dir.path());
    expectValues(vol, series);
    EXPECT_EQ(vol.spacing(), Vec3d(0.5, 0.75, 2.0));
    EXPECT_EQ(vol.origin(), series.corner);
    EXPECT_EQ(vol.units, "HU");
    EXPECT_EQ(vol.minValue, series.hu(0, 0, 0));
    EXPECT_EQ(vol.maxValue, series.hu(15, 11, 9));
}

TEST(DicomSynthetic, FlippedSeriesGivesTheSameCanonicalVolume)
{
    test::TempDir plainDir, flippedDir;
    Series plain;
    plain.write(plainDir.path());
    Series flipped;
    flipped.flipped = true; // column direction -y, normal -z, z decreasing in file order
    flipped.write(flippedDir.path());

    const vdb::DenseScan raw = vdb::readDicomSeries(flippedDir.path(), {}, nullptr);
    EXPECT_EQ(raw.geometry.direction.col(1), Vec3d(0, -1, 0));
    EXPECT_EQ(raw.geometry.direction.col(2), Vec3d(0, 0, -1));
    EXPECT_EQ(raw.geometry.origin, plain.corner + Vec3d(0, 11 * 0.75, 9 * 2.0));

    const vdb::Volume a = vdb::readVolume(plainDir.path());
    const vdb::Volume b = vdb::readVolume(flippedDir.path());
    expectValues(a, plain);
    expectValues(b, plain);
    EXPECT_EQ(a.origin(), b.origin());
    EXPECT_EQ(a.spacing(), b.spacing());
}

TEST(DicomSynthetic, TwoSeriesPickTheLargestOrTheNamedOne)
{
    test::TempDir dir;
    Series big;
    big.write(dir.path(), "A");
    Series small;
    small.slices = 4;
    small.uid = "1.2.826.0.1.3680043.9.7.1.2";
    small.offset = 1000;
    small.write(dir.path(), "B");
    writeText(dir.file("README.txt"), "DICOM export, two series\n");
    writeFakePng(dir.file("preview.png"));

    expectValues(vdb::readVolume(dir.path()), big);

    vdb::ReadOptions options;
    options.seriesUid = small.uid;
    expectValues(vdb::readVolume(dir.path(), options), small);

    // A file names its own series.
    expectValues(vdb::readVolume(dir.file(small.fileName("B", 2))), small);

    options.seriesUid = "1.2.3.4";
    const std::string message = readError(dir.path(), options);
    EXPECT_NE(message.find(dir.path()), std::string::npos) << message;
    EXPECT_NE(message.find("1.2.3.4"), std::string::npos) << message;
    EXPECT_NE(message.find(big.uid + " (10 slices)"), std::string::npos) << message;
    EXPECT_NE(message.find(small.uid + " (4 slices)"), std::string::npos) << message;
}

TEST(DicomSynthetic, NonDicomFilesAreIgnored)
{
    test::TempDir dir;
    Series series;
    series.write(dir.path());
    writeText(dir.file("README.txt"), "Exported by a scanner.\nPatient: anonymous\n");
    writeFakePng(dir.file("thumb.png"));
    writeText(dir.file("DICOMDIR.bak"), std::string(300, '\0'));
    std::filesystem::create_directory(dir.file("sub"));
    expectValues(vdb::readVolume(dir.path()), series);
}

TEST(DicomSynthetic, EmptyOrNonDicomFolderIsRejected)
{
    test::TempDir empty;
    std::string message = readError(empty.path());
    EXPECT_EQ(message, empty.path() + ": folder is empty (expected the files of a DICOM series)");

    test::TempDir other;
    writeText(other.file("README.txt"), "not an image\n");
    writeFakePng(other.file("a.png"));
    message = readError(other.path());
    EXPECT_EQ(message, other.path() + ": no DICOM images among its 2 files (none is a DICOM file)");
}

TEST(DicomSynthetic, MissingSliceIsRejectedNamingTheGap)
{
    test::TempDir dir;
    Series series;
    series.write(dir.path(), "IM", {5});
    const std::string message = readError(dir.path());
    // Slices 4 and 6 (positions) are files IM0001 and IM0005; they are slices 5 and 6 of 9 read.
    EXPECT_EQ(message, dir.path() + ": slice spacing is uneven: 4 mm between slice 5 (" + series.fileName("IM", 4) +
                           ") and slice 6 (" + series.fileName("IM", 6) +
                           ") in position order, 2 mm elsewhere (missing slice?)");
}

TEST(DicomSynthetic, DuplicatePositionIsRejected)
{
    test::TempDir dir;
    Series series;
    series.write(dir.path());
    series.writeSlice(dir.file("copy.dcm"), 3);
    const std::string message = readError(dir.path());
    EXPECT_NE(message.find("copy.dcm"), std::string::npos) << message;
    EXPECT_NE(message.find(series.fileName("IM", 3)), std::string::npos) << message;
    EXPECT_NE(message.find("duplicate slice"), std::string::npos) << message;
}

TEST(DicomSynthetic, ShearedStackIsRejected)
{
    test::TempDir dir;
    Series series;
    series.shear = 0.25;
    series.write(dir.path());
    const std::string message = readError(dir.path());
    EXPECT_EQ(message, dir.file(series.fileName("IM", 1)) + ": slice is offset 0.25 mm within its plane from " +
                           series.fileName("IM", 0) + " (sheared stack, gantry tilt?); resample the series first");
}

TEST(DicomSynthetic, SliceOfAnotherSizeIsRejected)
{
    test::TempDir dir;
    Series series;
    series.write(dir.path());
    const std::string odd = dir.file(series.fileName("IM", 6));
    series.writeSlice(odd, 6, 15);
    const std::string message = readError(dir.path());
    EXPECT_EQ(message.rfind(odd + ": slice is 15 x 12 pixels (columns x rows), expected 16 x 12", 0), 0u) << message;
}

TEST(DicomSynthetic, RgbIsRejected)
{
    test::TempDir dir;
    gdcm::ImageWriter writer;
    gdcm::Image& image = writer.GetImage();
    image.SetNumberOfDimensions(2);
    image.SetDimension(0, 4);
    image.SetDimension(1, 4);
    image.SetPixelFormat(gdcm::PixelFormat(3, 8, 8, 7));
    image.SetPhotometricInterpretation(gdcm::PhotometricInterpretation::RGB);
    const std::string rgb(4 * 4 * 3, '\x40');
    gdcm::DataElement data(gdcm::Tag(0x7fe0, 0x0010));
    data.SetByteValue(rgb.data(), uint32_t(rgb.size()));
    image.SetDataElement(data);
    writer.SetFileName(dir.file("photo.dcm").c_str());
    ASSERT_TRUE(writer.Write());
    const std::string message = readError(dir.path());
    EXPECT_EQ(message.rfind(dir.file("photo.dcm") + ": image has 3 samples per pixel (RGB)", 0), 0u) << message;
}

/// Stops once the reading passes half way; records what it was told.
struct StopHalfWay : Interrupter
{
    std::string name;
    std::atomic<int> maxPercent{-1};
    void start(const char* n) override { name = n ? n : ""; }
    bool wasInterrupted(int percent) override
    {
        int seen = maxPercent.load();
        while (percent > seen && !maxPercent.compare_exchange_weak(seen, percent)) {
        }
        return percent >= 50;
    }
};

TEST(DicomSynthetic, Cancellation)
{
    test::TempDir dir;
    Series series;
    series.write(dir.path());
    StopHalfWay stop;
    EXPECT_THROW(vdb::readDicomSeries(dir.path(), {}, &stop), Cancelled);
    EXPECT_EQ(stop.name, "reading DICOM");
    EXPECT_GE(stop.maxPercent.load(), 50);
}

// ---------------------------------------------------------------------------
// Real data

TEST(DicomRealData, VisibleHumanHead)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    const auto t0 = std::chrono::steady_clock::now();
    const vdb::DenseScan scan = vdb::readDicomSeries(dir, {}, nullptr);
    const auto t1 = std::chrono::steady_clock::now();
    const vdb::Volume vol = vdb::readVolume(dir);
    const auto t2 = std::chrono::steady_clock::now();
    std::printf("vhm-head-dicom: readDicomSeries %.3f s, readVolume (with makeVolume) %.3f s\n",
                std::chrono::duration<double>(t1 - t0).count(), std::chrono::duration<double>(t2 - t1).count());

    EXPECT_EQ(scan.geometry.dims, Coord(512, 512, 245));
    EXPECT_EQ(vol.dims, Coord(512, 512, 245));
    EXPECT_EQ(vol.spacing(), Vec3d(1.0, 1.0, 1.0));
    EXPECT_EQ(vol.origin(), Vec3d(0.0, 0.0, 1000.0)); // synthetic positions (0,0,1000 + slice)
    EXPECT_EQ(vol.units, "HU");
    EXPECT_EQ(vol.minValue, -1024.0f);
    EXPECT_EQ(vol.maxValue, 3617.0f);

    EXPECT_EQ(voxel(vol, 0, 0, 120), -1024.0f);    // air
    EXPECT_EQ(voxel(vol, 256, 224, 200), 20.0f);   // brain
    EXPECT_EQ(voxel(vol, 224, 160, 200), -20.0f);  // soft tissue of the forehead
    EXPECT_EQ(voxel(vol, 256, 160, 200), 1036.0f); // frontal bone
    EXPECT_EQ(voxel(vol, 192, 256, 200), 861.0f);  // parietal bone
    EXPECT_EQ(voxel(vol, 192, 256, 120), 472.0f);

    // Orientation: the head narrows towards its vertex at +z (the top slices
    // still cut the skull cap), the neck and shoulders are at low k.
    const auto area = [&](int k, float threshold) {
        const auto acc = vol.grid->getConstAccessor();
        int count = 0;
        for (int j = 0; j < 512; ++j) {
            for (int i = 0; i < 512; ++i) count += acc.getValue(Coord(i, j, k)) >= threshold;
        }
        return count;
    };
    EXPECT_GT(area(244, 400.0f), 1000); // skull cap in the topmost slice
    const int top = area(240, -500.0f), crown = area(220, -500.0f), brain = area(180, -500.0f);
    const int shoulders = area(0, -500.0f);
    EXPECT_LT(top, crown);
    EXPECT_LT(crown, brain);
    EXPECT_GT(shoulders, brain);
    // LPS: the face is anterior (low j), the scanner table posterior (high j).
    int faceJ = 512;
    for (int j = 0; j < 512 && faceJ == 512; ++j) {
        for (int i = 0; i < 512; ++i) {
            if (voxel(vol, i, j, 120) > -500.0f) {
                faceJ = j;
                break;
            }
        }
    }
    EXPECT_LT(faceJ, 200);
}

TEST(DicomRealData, Jpeg2000BodyCt)
{
    MTCUT_REQUIRE_DATA(dir, "body-ct-dicom-j2k");
    const vdb::Volume vol = vdb::readVolume(dir);
    EXPECT_EQ(vol.dims, Coord(512, 512, 20));
    // PixelSpacing 0.9765625, positions z = -804.5 .. -766.5 in 2 mm steps (SliceThickness is 3).
    EXPECT_EQ(vol.spacing(), Vec3d(0.9765625, 0.9765625, 2.0));
    EXPECT_EQ(vol.origin(), Vec3d(-249.51171875, -437.51171875, -804.5));
    EXPECT_EQ(vol.units, "HU");
    EXPECT_EQ(vol.minValue, -1024.0f);
    EXPECT_EQ(vol.maxValue, 1839.0f);
    EXPECT_EQ(voxel(vol, 0, 0, 0), -1024.0f);
    EXPECT_EQ(voxel(vol, 128, 256, 0), 95.0f);   // soft tissue
    EXPECT_EQ(voxel(vol, 224, 320, 0), 809.0f);  // bone
    EXPECT_EQ(voxel(vol, 160, 192, 10), 918.0f); // bone
}

TEST(DicomRealData, CliInfo)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    const test::RunResult r = test::runMtcut("info '" + dir + "'");
    EXPECT_EQ(r.exitCode, 0) << r.output;
    EXPECT_NE(r.output.find("512 x 512 x 245"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("spacing:   1 mm"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("(DICOM)"), std::string::npos) << r.output;
}

} // namespace
} // namespace mtcut
