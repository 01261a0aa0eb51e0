#include "render/Frame.h"

#include "vdb/AtomicFile.h"
#include "vdb/Error.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>
#include <half.h>
#include <png.h>

#include <cstdio>
#include <memory>
#include <stdexcept>

namespace mtcut::render {

namespace {

struct FileCloser
{
    void operator()(FILE* f) const { std::fclose(f); }
};

void pngError(png_structp png, png_const_charp message)
{
    auto* what = static_cast<std::string*>(png_get_error_ptr(png));
    *what = message ? message : "libpng error";
    png_longjmp(png, 1);
}

void pngWarning(png_structp, png_const_charp) {}

void checkFrame(const Frame& frame, const std::string& path)
{
    if (frame.width <= 0 || frame.height <= 0 || frame.rgba.size() != frame.pixelCount() * 4) {
        throw InputError(path + ": empty or malformed frame");
    }
}

} // namespace

void writePng(const Frame& frame, const std::string& path)
{
    checkFrame(frame, path);
    writeFileAtomically(path, [&](const std::string& tmp) {
        std::unique_ptr<FILE, FileCloser> file(std::fopen(tmp.c_str(), "wb"));
        if (!file) throw InputError(path + ": cannot create the file");
        std::string error;
        png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &error, pngError, pngWarning);
        png_infop info = png ? png_create_info_struct(png) : nullptr;
        if (!png || !info) {
            png_destroy_write_struct(&png, nullptr);
            throw InputError(path + ": libpng could not start");
        }
        std::vector<png_bytep> rows(size_t(frame.height));
        for (int y = 0; y < frame.height; ++y) {
            rows[size_t(y)] = const_cast<png_bytep>(frame.rgba.data() + size_t(y) * size_t(frame.width) * 4);
        }
        if (setjmp(png_jmpbuf(png))) {
            png_destroy_write_struct(&png, &info);
            throw InputError(path + ": " + error);
        }
        png_init_io(png, file.get());
        png_set_IHDR(png, info, png_uint_32(frame.width), png_uint_32(frame.height), 8, PNG_COLOR_TYPE_RGB_ALPHA,
                     PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
        png_write_info(png, info);
        png_write_image(png, rows.data());
        png_write_end(png, nullptr);
        png_destroy_write_struct(&png, &info);
        if (std::fflush(file.get()) != 0 || std::ferror(file.get())) throw InputError(path + ": write failed");
        FILE* f = file.release();
        if (std::fclose(f) != 0) throw InputError(path + ": write failed");
    });
}

Frame readPng(const std::string& path)
{
    std::unique_ptr<FILE, FileCloser> file(std::fopen(path.c_str(), "rb"));
    if (!file) throw InputError(path + ": cannot open");
    std::string error;
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &error, pngError, pngWarning);
    png_infop info = png ? png_create_info_struct(png) : nullptr;
    if (!png || !info) {
        png_destroy_read_struct(&png, nullptr, nullptr);
        throw InputError(path + ": libpng could not start");
    }
    Frame frame;
    std::vector<png_bytep> rows;
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_read_struct(&png, &info, nullptr);
        throw InputError(path + ": " + error);
    }
    png_init_io(png, file.get());
    png_read_info(png, info);
    png_set_expand(png);
    png_set_strip_16(png);
    png_set_gray_to_rgb(png);
    png_set_add_alpha(png, 0xff, PNG_FILLER_AFTER);
    png_read_update_info(png, info);
    frame.width = int(png_get_image_width(png, info));
    frame.height = int(png_get_image_height(png, info));
    frame.rgba.resize(frame.pixelCount() * 4);
    rows.resize(size_t(frame.height));
    for (int y = 0; y < frame.height; ++y) rows[size_t(y)] = frame.rgba.data() + size_t(y) * size_t(frame.width) * 4;
    png_read_image(png, rows.data());
    png_read_end(png, nullptr);
    png_destroy_read_struct(&png, &info, nullptr);
    return frame;
}

void writeExr(const Frame& frame, const std::string& path)
{
    checkFrame(frame, path);
    const size_t n = frame.pixelCount();
    if (frame.depth.size() != n || frame.normals.size() != n || frame.fragments.size() != n) {
        throw InputError(path + ": the frame has no depth, normal or fragment channels");
    }
    std::vector<half> colour(n * 4);
    for (size_t i = 0; i < n * 4; ++i) colour[i] = half(float(frame.rgba[i]) / 255.0f);
    writeFileAtomically(path, [&](const std::string& tmp) {
        try {
            Imf::Header header(frame.width, frame.height);
            header.compression() = Imf::ZIP_COMPRESSION;
            header.insert("software", Imf::StringAttribute("mtcut render"));
            Imf::ChannelList& ch = header.channels();
            for (const char* c : {"R", "G", "B", "A"}) ch.insert(c, Imf::Channel(Imf::HALF));
            for (const char* c : {"Z", "N.X", "N.Y", "N.Z"}) ch.insert(c, Imf::Channel(Imf::FLOAT));
            ch.insert("fragment", Imf::Channel(Imf::UINT));
            Imf::FrameBuffer fb;
            const size_t xs = sizeof(half) * 4, ys = xs * size_t(frame.width);
            const char* base = reinterpret_cast<const char*>(colour.data());
            fb.insert("R", Imf::Slice(Imf::HALF, const_cast<char*>(base), xs, ys));
            fb.insert("G", Imf::Slice(Imf::HALF, const_cast<char*>(base + sizeof(half)), xs, ys));
            fb.insert("B", Imf::Slice(Imf::HALF, const_cast<char*>(base + 2 * sizeof(half)), xs, ys));
            fb.insert("A", Imf::Slice(Imf::HALF, const_cast<char*>(base + 3 * sizeof(half)), xs, ys));
            fb.insert("Z", Imf::Slice(Imf::FLOAT, const_cast<char*>(reinterpret_cast<const char*>(frame.depth.data())),
                                      sizeof(float), sizeof(float) * size_t(frame.width)));
            const char* nb = reinterpret_cast<const char*>(frame.normals.data());
            const size_t nxs = sizeof(glm::vec3), nys = nxs * size_t(frame.width);
            fb.insert("N.X", Imf::Slice(Imf::FLOAT, const_cast<char*>(nb), nxs, nys));
            fb.insert("N.Y", Imf::Slice(Imf::FLOAT, const_cast<char*>(nb + sizeof(float)), nxs, nys));
            fb.insert("N.Z", Imf::Slice(Imf::FLOAT, const_cast<char*>(nb + 2 * sizeof(float)), nxs, nys));
            fb.insert("fragment",
                      Imf::Slice(Imf::UINT, const_cast<char*>(reinterpret_cast<const char*>(frame.fragments.data())),
                                 sizeof(uint32_t), sizeof(uint32_t) * size_t(frame.width)));
            Imf::OutputFile out(tmp.c_str(), header);
            out.setFrameBuffer(fb);
            out.writePixels(frame.height);
        } catch (const InputError&) {
            throw;
        } catch (const std::exception& e) {
            throw InputError(path + ": " + e.what());
        }
    });
}

} // namespace mtcut::render
