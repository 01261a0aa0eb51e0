// A rendered frame on the CPU, and its files: PNG (8-bit RGBA, for people)
// and OpenEXR (RGBA, depth, normal and fragment-id channels, for compositing
// tools). No GL here.
#pragma once

#include <glm/vec3.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace mtcut::render {

/// Pixels row by row, the top row first, left to right.
struct Frame
{
    int width = 0, height = 0;
    std::vector<uint8_t> rgba;        ///< 4 per pixel, straight alpha (0 = background)
    std::vector<float> depth;         ///< mm along the view direction; +infinity where no surface
    std::vector<glm::vec3> normals;   ///< unit world normals facing the viewer; 0 where no surface
    std::vector<uint32_t> fragments;  ///< fragment id (1 = fragment_000, ...); 0 where no surface

    size_t pixelCount() const { return size_t(width) * size_t(height); }
};

/// Writes frame.rgba as an 8-bit RGBA PNG (libpng), atomically (a temporary
/// file renamed; nothing is left on error). Throws InputError naming the file.
void writePng(const Frame& frame, const std::string& path);

/// Writes a scanline OpenEXR (ZIP) with channels R, G, B, A (half: the 8-bit
/// colour / 255, as displayed, not linearised), Z (float, depth in mm, +inf where no
/// surface), N.X, N.Y, N.Z (float, world normal) and fragment (uint, fragment
/// id, 0 where no surface), atomically. Throws InputError naming the file.
void writeExr(const Frame& frame, const std::string& path);

/// Reads an 8-bit RGBA PNG back (tests and tools): width, height, rgba.
Frame readPng(const std::string& path);

} // namespace mtcut::render
