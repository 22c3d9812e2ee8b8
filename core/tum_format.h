// The TUM RGB-D text formats, in one place: timestamps (seconds with up to nanosecond digits) and
// trajectories (`timestamp tx ty tz qx qy qz qw` per line, pose world_from_cam, `#` comments,
// fields separated by spaces or commas as TUM's own tools accept). Timestamps are parsed as
// decimal text, never through a double (16 significant digits do not fit one), and written with
// nine fraction digits, so a write-read round trip is exact.
#pragma once

#include <functional>
#include <istream>
#include <string>
#include <vector>

#include "core/rgbd_frame.h"

namespace sightmap {

// "1305031102.175304" -> 1305031102175304000 ns. Digits past the ninth round half up; an exponent
// ("1.3e9") is taken through long double. False for anything else, or beyond +-9e9 s.
bool ParseTimestampNs(const std::string& text, TimestampNs* ns);
// 1305031102175304000 ns -> "1305031102.175304000".
std::string FormatTimestamp(TimestampNs ns);

// A whole field as a finite number ("1.5", "-2e3"); false for "", "1.5x", "nan" or "inf".
bool ParseFiniteDouble(const std::string& text, double* value);

// Throws Error "<path>:<line_number>: expected <expected> but found "<line>"; fix or delete the
// line": what every reader of a line-based text file says about a line it cannot read.
[[noreturn]] void ThrowMalformedLine(const std::string& path, int line_number,
                                     const std::string& line, const std::string& expected);

// Calls fields_of_line(fields, line_number, line) for every line of `in` that is neither blank nor
// a '#' comment: its fields separated by spaces or commas, its 1-based number, and the line as
// written (a trailing '\r' dropped), for error messages.
void ForEachTumLine(std::istream& in,
                    const std::function<void(const std::vector<std::string>&, int,
                                             const std::string&)>& fields_of_line);

// Poses in file order. Throws Error naming the file, the line and what it expected ("fix or
// delete the line") for a malformed line or a zero quaternion; quaternions are normalised.
std::vector<StampedPose> ReadTumTrajectory(const std::string& path);
// Through an AtomicFile, after `comment` (one "# " line, when given) and the format's header;
// translations to the nanometre, quaternions to 12 digits.
void WriteTumTrajectory(const std::string& path, const std::vector<StampedPose>& poses,
                        const std::string& comment = "");

}  // namespace sightmap
