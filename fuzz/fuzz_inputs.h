// What the fuzz harnesses and the seed writer share: one fuzz input stands for several files
// (a TUM folder's lists, a 3DMatch sequence's text files), their contents joined by a NUL byte,
// which none of those text files holds; and a scratch folder for the files a parser reads by path.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace sightmap::fuzz {

// `parts` contents joined by NUL bytes.
std::string JoinParts(const std::vector<std::string>& parts);
// The first `count` NUL-separated parts of an input (missing parts are empty; the last part
// keeps any further NULs).
std::vector<std::string> SplitParts(const uint8_t* data, size_t size, size_t count);

// Writes the input's first names.size() NUL-separated parts to dir/names[i].
void WriteParts(const uint8_t* data, size_t size, const std::string& dir,
                const std::vector<std::string>& names);

// A frame's two images as an RGB-D folder holds them: 16x12 colour (8-bit BGR) and depth
// (16-bit, 5 m everywhere) PNGs.
void WriteTinyFrame(const std::string& color_path, const std::string& depth_path);

// A folder of this process's own under the system's temporary folder, made on first use.
const std::string& ScratchDir();
// Writes `bytes` to `path` (replacing it); aborts when it cannot, which is the harness's fault.
void WriteFile(const std::string& path, const std::string& bytes);

}  // namespace sightmap::fuzz
