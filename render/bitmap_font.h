// A 5x7 bitmap font for ASCII 32-126 (our own glyph table), because OSMesa and legacy GL have no
// text. Text is drawn as filled squares, one per lit font pixel, either as GL triangles (the map
// renderer, in any context) or straight into a cv::Mat.
#pragma once

#include <array>
#include <cstdint>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace sightmap::render {

constexpr int kGlyphWidth = 5;    // font pixels
constexpr int kGlyphHeight = 7;   // font pixels
constexpr int kGlyphAdvance = 6;  // font pixels from one character to the next
constexpr int kLineAdvance = 9;   // font pixels from one line to the next ('\n')

// Rows top first; bit 4 is the leftmost column. Characters outside 32-126 map to '?'.
const std::array<uint8_t, kGlyphHeight>& Glyph5x7(char c);

// Size of `text` drawn with `scale` screen pixels per font pixel [px]; '\n' starts a new line.
int TextWidthPx(std::string_view text, int scale);
int TextHeightPx(std::string_view text, int scale);

// Appends two triangles (six vertices) per lit font pixel: screen pixels, x right, y down, the
// text's top-left corner at (x, y).
void AppendTextTriangles(std::string_view text, float x, float y, float scale,
                         std::vector<Eigen::Vector2f>* triangles);

// Draws `text` into an 8-bit 3-channel image with its top-left corner at `top_left` (clipped).
void DrawText(std::string_view text, cv::Point top_left, int scale, const cv::Vec3b& color,
              cv::Mat* image);

}  // namespace sightmap::render
