// DICOM series -> DenseScan through GDCM: gdcm::Directory lists the folder,
// gdcm::Scanner reads the header tags of every file (stopping before the
// pixel data), gdcm::ImageReader decodes each slice (any transfer syntax GDCM
// supports, JPEG 2000 included). We group by SeriesInstanceUID, sort along the
// slice normal, check that the stack is a regular grid, and apply the
// per-slice rescale.
#include "vdb/Formats.h"

#include <gdcmDirectory.h>
#include <gdcmImage.h>
#include <gdcmImageReader.h>
#include <gdcmPixelFormat.h>
#include <gdcmScanner.h>
#include <gdcmTag.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <sstream>
#include <vector>

namespace mtcut::vdb {

namespace {

namespace fs = std::filesystem;

const gdcm::Tag kModality(0x0008, 0x0060);
const gdcm::Tag kSliceThickness(0x0018, 0x0050);
const gdcm::Tag kSeriesUid(0x0020, 0x000e);
const gdcm::Tag kPosition(0x0020, 0x0032);    // ImagePositionPatient
const gdcm::Tag kOrientation(0x0020, 0x0037); // ImageOrientationPatient
const gdcm::Tag kSamplesPerPixel(0x0028, 0x0002);
const gdcm::Tag kPhotometric(0x0028, 0x0004);
const gdcm::Tag kNumberOfFrames(0x0028, 0x0008);
const gdcm::Tag kRows(0x0028, 0x0010);
const gdcm::Tag kColumns(0x0028, 0x0011);
const gdcm::Tag kPixelSpacing(0x0028, 0x0030);
const gdcm::Tag kRescaleIntercept(0x0028, 0x1052);
const gdcm::Tag kRescaleSlope(0x0028, 0x1053);
const gdcm::Tag kRescaleType(0x0028, 0x1054);

std::string baseName(const std::string& path) { return fs::path(path).filename().string(); }

std::string trim(const char* value)
{
    if (!value) return {};
    std::string s(value);
    const auto notPad = [](char c) { return c != ' ' && c != '\0' && c != '\t' && c != '\r' && c != '\n'; };
    const auto first = std::find_if(s.begin(), s.end(), notPad);
    const auto last = std::find_if(s.rbegin(), s.rend(), notPad).base();
    return first < last ? std::string(first, last) : std::string();
}

std::string num(double v)
{
    std::ostringstream os;
    os << v;
    return os.str();
}

/// Backslash-separated decimal strings (DICOM DS/IS), locale-independent.
/// Empty when any component is not a finite number.
std::vector<double> parseNumbers(const std::string& text)
{
    std::vector<double> out;
    size_t start = 0;
    while (start <= text.size()) {
        size_t end = text.find('\\', start);
        if (end == std::string::npos) end = text.size();
        std::string part = trim(text.substr(start, end - start).c_str());
        if (!part.empty() && part[0] == '+') part.erase(0, 1);
        double v = 0.0;
        const auto [ptr, ec] = std::from_chars(part.data(), part.data() + part.size(), v);
        if (part.empty() || ec != std::errc() || ptr != part.data() + part.size() || !std::isfinite(v)) return {};
        out.push_back(v);
        start = end + 1;
    }
    return out;
}

/// Header of one slice, as the scanner read it.
struct SliceInfo
{
    std::string path;
    openvdb::Vec3d position{0.0}; ///< ImagePositionPatient, LPS mm
    double normalPos = 0.0;       ///< position projected on the slice normal
    double slope = 1.0;
    double intercept = 0.0;
};

class DicomSeriesReader
{
public:
    DicomSeriesReader(const std::string& input, const ReadOptions& options, Interrupter* interrupter)
        : mInput(input), mOptions(options), mInterrupter(interrupter)
    {
    }

    DenseScan read()
    {
        InterrupterScope scope(mInterrupter, "reading DICOM");
        scanFolder();
        const std::vector<std::string> files = pickSeries();
        pollInterrupter(mInterrupter, 0);
        std::vector<SliceInfo> slices = readHeaders(files);
        DenseScan scan;
        scan.geometry = sortAndMeasure(slices);
        scan.units = units(slices.front().path);
        decode(slices, scan);
        return scan;
    }

private:
    std::string mInput;
    const ReadOptions& mOptions;
    Interrupter* mInterrupter;
    std::string mFolder;   ///< the folder the series comes from (names the errors)
    std::string mOneFile;  ///< when the input is a file: that file
    gdcm::Scanner mScanner;
    std::vector<std::string> mImages; ///< files the scanner read that have Rows and Columns

    [[noreturn]] void fail(const std::string& what) const { throw InputError(mFolder + ": " + what); }
    [[noreturn]] static void failFile(const std::string& path, const std::string& what)
    {
        throw InputError(path + ": " + what);
    }

    std::string value(const std::string& path, const gdcm::Tag& tag) const
    {
        return trim(mScanner.GetValue(path.c_str(), tag));
    }

    void scanFolder()
    {
        std::error_code ec;
        const auto status = fs::status(mInput, ec);
        if (ec || !fs::exists(status)) throw InputError(mInput + ": no such file or folder");
        if (fs::is_directory(status)) {
            mFolder = mInput;
        } else {
            mOneFile = mInput;
            const fs::path parent = fs::path(mInput).parent_path();
            mFolder = parent.empty() ? std::string(".") : parent.string();
        }

        gdcm::Directory directory;
        directory.Load(mFolder, false);
        gdcm::Directory::FilenamesType files = directory.GetFilenames();
        if (files.empty()) fail("folder is empty (expected the files of a DICOM series)");
        std::sort(files.begin(), files.end());

        for (const gdcm::Tag& tag : {kModality, kSliceThickness, kSeriesUid, kPosition, kOrientation, kSamplesPerPixel,
                                     kPhotometric, kNumberOfFrames, kRows, kColumns, kPixelSpacing, kRescaleIntercept,
                                     kRescaleSlope, kRescaleType}) {
            mScanner.AddTag(tag);
        }
        pollInterrupter(mInterrupter, 0);
        if (!mScanner.Scan(files)) fail("cannot scan the folder's files");

        size_t dicomFiles = 0;
        for (const std::string& f : files) {
            if (!mScanner.IsKey(f.c_str())) continue;
            ++dicomFiles;
            if (!value(f, kRows).empty() && !value(f, kColumns).empty()) mImages.push_back(f);
        }
        if (mImages.empty()) {
            fail("no DICOM images among its " + std::to_string(files.size()) + " files (" +
                 (dicomFiles == 0 ? std::string("none is a DICOM file")
                                  : std::to_string(dicomFiles) + " DICOM files without pixel data") +
                 ")");
        }
    }

    /// The files of the series to read, in file-name order.
    std::vector<std::string> pickSeries() const
    {
        std::map<std::string, std::vector<std::string>> series;
        for (const std::string& f : mImages) series[value(f, kSeriesUid)].push_back(f);

        std::string uid = mOptions.seriesUid;
        if (uid.empty() && !mOneFile.empty()) {
            const auto it = std::find_if(mImages.begin(), mImages.end(), [&](const std::string& f) {
                std::error_code ec;
                return fs::equivalent(f, mOneFile, ec);
            });
            if (it == mImages.end()) failFile(mOneFile, "not a DICOM image");
            uid = value(*it, kSeriesUid);
        }
        if (uid.empty()) {
            // The series with the most slices; ties go to the smallest UID (map order).
            auto best = series.begin();
            for (auto it = series.begin(); it != series.end(); ++it) {
                if (it->second.size() > best->second.size()) best = it;
            }
            return best->second;
        }
        const auto it = series.find(uid);
        if (it == series.end()) {
            std::string list;
            for (const auto& [u, f] : series) {
                list += (list.empty() ? "" : ", ") + (u.empty() ? std::string("(no UID)") : u) + " (" +
                        std::to_string(f.size()) + (f.size() == 1 ? " slice)" : " slices)");
            }
            fail("no series with SeriesInstanceUID " + uid + "; available: " + list);
        }
        return it->second;
    }

    /// Parses and cross-checks the header of every slice against the first file.
    std::vector<SliceInfo> readHeaders(const std::vector<std::string>& files)
    {
        // Pixel layout first: an RGB or multi-frame file also lacks the CT geometry tags.
        for (const std::string& f : files) {
            const std::string samples = value(f, kSamplesPerPixel);
            if (!samples.empty() && samples != "1") {
                failFile(f, "image has " + samples + " samples per pixel (" + value(f, kPhotometric) +
                                "); only grayscale (1 sample) is supported");
            }
            const std::string frames = value(f, kNumberOfFrames);
            if (!frames.empty() && frames != "1") {
                failFile(f, "multi-frame image (" + frames + " frames); only single-frame slices are supported");
            }
        }
        const std::string& ref = files.front();
        mRows = parseSize(ref, kRows, "Rows");
        mColumns = parseSize(ref, kColumns, "Columns");
        mOrientation = parseVector(ref, kOrientation, 6, "ImageOrientationPatient (0020,0037)");
        mPixelSpacing = parseVector(ref, kPixelSpacing, 2, "PixelSpacing (0028,0030)");
        if (!(mPixelSpacing[0] > 0.0 && mPixelSpacing[1] > 0.0)) {
            failFile(ref, "PixelSpacing " + value(ref, kPixelSpacing) + " is not positive");
        }

        std::vector<SliceInfo> slices;
        slices.reserve(files.size());
        for (const std::string& f : files) {
            if (f != ref) {
                const int rows = parseSize(f, kRows, "Rows");
                const int columns = parseSize(f, kColumns, "Columns");
                if (rows != mRows || columns != mColumns) {
                    failFile(f, "slice is " + std::to_string(columns) + " x " + std::to_string(rows) +
                                    " pixels (columns x rows), expected " + std::to_string(mColumns) + " x " +
                                    std::to_string(mRows) + " as in " + baseName(ref));
                }
                const auto o = parseVector(f, kOrientation, 6, "ImageOrientationPatient (0020,0037)");
                for (int a = 0; a < 6; ++a) {
                    if (std::abs(o[a] - mOrientation[a]) > 1e-4) {
                        failFile(f, "ImageOrientationPatient " + value(f, kOrientation) + " differs from " +
                                        value(ref, kOrientation) + " in " + baseName(ref));
                    }
                }
                const auto s = parseVector(f, kPixelSpacing, 2, "PixelSpacing (0028,0030)");
                for (int a = 0; a < 2; ++a) {
                    if (std::abs(s[a] - mPixelSpacing[a]) > 1e-4 * mPixelSpacing[a]) {
                        failFile(f, "PixelSpacing " + value(f, kPixelSpacing) + " differs from " +
                                        value(ref, kPixelSpacing) + " in " + baseName(ref));
                    }
                }
            }
            SliceInfo info;
            info.path = f;
            const auto p = parseVector(f, kPosition, 3, "ImagePositionPatient (0020,0032)");
            info.position = openvdb::Vec3d(p[0], p[1], p[2]);
            if (!value(f, kRescaleSlope).empty()) {
                info.slope = parseVector(f, kRescaleSlope, 1, "RescaleSlope (0028,1053)")[0];
                if (info.slope == 0.0) failFile(f, "RescaleSlope is 0");
            }
            if (!value(f, kRescaleIntercept).empty()) {
                info.intercept = parseVector(f, kRescaleIntercept, 1, "RescaleIntercept (0028,1052)")[0];
            }
            slices.push_back(std::move(info));
        }
        return slices;
    }

    int parseSize(const std::string& path, const gdcm::Tag& tag, const char* name) const
    {
        const std::string text = value(path, tag);
        const std::vector<double> v = parseNumbers(text);
        if (v.size() != 1 || v[0] < 1 || v[0] > kMaxDim || v[0] != std::floor(v[0])) {
            failFile(path, std::string(name) + " '" + text + "' is not a positive size");
        }
        return int(v[0]);
    }

    std::vector<double> parseVector(const std::string& path, const gdcm::Tag& tag, size_t count,
                                    const char* name) const
    {
        const std::string text = value(path, tag);
        if (text.empty()) failFile(path, std::string("missing ") + name);
        std::vector<double> v = parseNumbers(text);
        if (v.size() != count) {
            failFile(path, std::string(name) + " '" + text + "': expected " + std::to_string(count) + " numbers");
        }
        return v;
    }

    /// Sorts the slices along the normal and checks the stack is a regular grid.
    VolumeGeometry sortAndMeasure(std::vector<SliceInfo>& slices) const
    {
        const std::string& ref = slices.front().path;
        openvdb::Vec3d rowDir(mOrientation[0], mOrientation[1], mOrientation[2]);
        openvdb::Vec3d colDir(mOrientation[3], mOrientation[4], mOrientation[5]);
        if (rowDir.length() < 0.5 || colDir.length() < 0.5 || std::abs(rowDir.unitSafe().dot(colDir.unitSafe())) > 1e-3) {
            failFile(ref, "ImageOrientationPatient " + value(ref, kOrientation) +
                              " is not two orthogonal unit vectors");
        }
        rowDir.normalize();
        colDir.normalize();
        const openvdb::Vec3d normal = rowDir.cross(colDir).unitSafe();

        for (SliceInfo& s : slices) s.normalPos = s.position.dot(normal);
        std::sort(slices.begin(), slices.end(), [](const SliceInfo& a, const SliceInfo& b) {
            return a.normalPos < b.normalPos || (a.normalPos == b.normalPos && a.path < b.path);
        });

        const size_t n = slices.size();
        double step = 0.0;
        if (n == 1) {
            const auto t = parseNumbers(value(ref, kSliceThickness));
            step = t.size() == 1 && t[0] > 0.0 ? t[0] : 1.0;
        } else {
            std::vector<double> steps(n - 1);
            for (size_t k = 0; k + 1 < n; ++k) {
                steps[k] = slices[k + 1].normalPos - slices[k].normalPos;
                if (steps[k] < 1e-3) {
                    fail(baseName(slices[k].path) + " and " + baseName(slices[k + 1].path) +
                         " have the same position (" + num(slices[k].normalPos) +
                         " mm along the slice normal): duplicate slice");
                }
            }
            std::vector<double> sorted = steps;
            std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
            const double median = sorted[sorted.size() / 2];
            const double tolerance = std::max(0.01, 0.01 * median);
            size_t bad = 0;
            size_t first = 0;
            for (size_t k = 0; k + 1 < n; ++k) {
                if (std::abs(steps[k] - median) > tolerance && bad++ == 0) first = k;
            }
            if (bad > 0) {
                const double ratio = steps[first] / median;
                const bool missing = ratio > 1.5 && std::abs(ratio - std::round(ratio)) < 0.05;
                fail("slice spacing is uneven: " + num(steps[first]) + " mm between slice " + std::to_string(first + 1) +
                     " (" + baseName(slices[first].path) + ") and slice " + std::to_string(first + 2) + " (" +
                     baseName(slices[first + 1].path) + ") in position order, " + num(median) + " mm elsewhere" +
                     (missing ? " (missing slice?)" : "") +
                     (bad > 1 ? "; " + std::to_string(bad - 1) + " more uneven step(s)" : ""));
            }
            step = (slices.back().normalPos - slices.front().normalPos) / double(n - 1);

            // Positions must move along the normal only (a gantry tilt shears the stack).
            const double shearTolerance = std::max(0.01, 0.01 * std::min(mPixelSpacing[0], mPixelSpacing[1]));
            for (const SliceInfo& s : slices) {
                const openvdb::Vec3d d = s.position - slices.front().position;
                const double offset = (d - normal * d.dot(normal)).length();
                if (offset > shearTolerance) {
                    failFile(s.path, "slice is offset " + num(offset) + " mm within its plane from " +
                                         baseName(slices.front().path) +
                                         " (sheared stack, gantry tilt?); resample the series first");
                }
            }
        }

        VolumeGeometry g;
        g.dims = openvdb::Coord(mColumns, mRows, int(std::min<size_t>(n, size_t(kMaxDim) + 1)));
        checkDims(g.dims, mFolder);
        g.spacing = openvdb::Vec3d(mPixelSpacing[1], mPixelSpacing[0], step);
        g.origin = slices.front().position;
        g.direction.setColumns(rowDir, colDir, normal);
        return g;
    }

    std::string units(const std::string& ref) const
    {
        if (value(ref, kModality) == "CT" || value(ref, kRescaleType) == "HU") return "HU";
        return {};
    }

    /// Decodes all slices in parallel into scan.values, rescale applied.
    void decode(const std::vector<SliceInfo>& slices, DenseScan& scan) const
    {
        const size_t n = slices.size();
        const size_t sliceSize = size_t(mColumns) * size_t(mRows);
        scan.values.resize(sliceSize * n);
        std::atomic<size_t> done{0};
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1), [&](const tbb::blocked_range<size_t>& range) {
            std::vector<char> buffer;
            for (size_t k = range.begin(); k != range.end(); ++k) {
                pollInterrupter(mInterrupter, int(100 * done.load() / n));
                decodeSlice(slices[k], buffer, scan.values.data() + k * sliceSize);
                ++done;
            }
        });
        pollInterrupter(mInterrupter, 100);
    }

    void decodeSlice(const SliceInfo& slice, std::vector<char>& buffer, float* out) const
    {
        gdcm::ImageReader reader;
        reader.SetFileName(slice.path.c_str());
        if (!reader.Read()) failFile(slice.path, "cannot read the DICOM image");
        const gdcm::Image& image = reader.GetImage();
        if (int(image.GetColumns()) != mColumns || int(image.GetRows()) != mRows) {
            failFile(slice.path, "decoded image is " + std::to_string(image.GetColumns()) + " x " +
                                     std::to_string(image.GetRows()) + " pixels, header says " +
                                     std::to_string(mColumns) + " x " + std::to_string(mRows));
        }
        const gdcm::PixelFormat& format = image.GetPixelFormat();
        if (format.GetSamplesPerPixel() != 1) {
            failFile(slice.path, "image has " + std::to_string(format.GetSamplesPerPixel()) +
                                     " samples per pixel (RGB?); only grayscale is supported");
        }
        const size_t count = size_t(mColumns) * size_t(mRows);
        buffer.resize(image.GetBufferLength());
        if (!image.GetBuffer(buffer.data())) {
            failFile(slice.path, "cannot decode the pixel data (transfer syntax " +
                                     std::string(gdcm::TransferSyntax::GetTSString(image.GetTransferSyntax())) + ")");
        }
        const double slope = slice.slope;
        const double intercept = slice.intercept;
        const auto convert = [&](auto zero) {
            using T = decltype(zero);
            if (buffer.size() < count * sizeof(T)) {
                failFile(slice.path, "pixel data is " + std::to_string(buffer.size()) + " bytes, expected " +
                                         std::to_string(count * sizeof(T)));
            }
            for (size_t i = 0; i < count; ++i) {
                T v;
                std::memcpy(&v, buffer.data() + i * sizeof(T), sizeof(T));
                out[i] = float(double(v) * slope + intercept);
            }
        };
        switch (format.GetScalarType()) {
        case gdcm::PixelFormat::UINT8: return convert(uint8_t());
        case gdcm::PixelFormat::INT8: return convert(int8_t());
        case gdcm::PixelFormat::UINT16: return convert(uint16_t());
        case gdcm::PixelFormat::INT16: return convert(int16_t());
        case gdcm::PixelFormat::UINT32: return convert(uint32_t());
        case gdcm::PixelFormat::INT32: return convert(int32_t());
        case gdcm::PixelFormat::FLOAT32: return convert(float());
        case gdcm::PixelFormat::FLOAT64: return convert(double());
        default: break;
        }
        failFile(slice.path, std::string("unsupported pixel type ") + format.GetScalarTypeAsString() +
                                 " (expected 8, 16 or 32-bit integers or floats)");
    }

    int mRows = 0;
    int mColumns = 0;
    std::vector<double> mOrientation;
    std::vector<double> mPixelSpacing;
};

} // namespace

DenseScan readDicomSeries(const std::string& folder, const ReadOptions& options, Interrupter* interrupter)
{
    return DicomSeriesReader(folder, options, interrupter).read();
}

} // namespace mtcut::vdb
