#include "store/label_files.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <map>

#include "core/atomic_file.h"
#include "core/check.h"
#include "core/input_file.h"
#include "core/tum_format.h"

namespace sightmap::store {
namespace {

// Parses three leading numbers separated by spaces, tabs, commas or semicolons.
bool ParsePoint(const std::string& line, Eigen::Vector3d* point) {
  const char* cursor = line.c_str();
  for (int i = 0; i < 3; ++i) {
    while (*cursor == ' ' || *cursor == '\t' || *cursor == ',' || *cursor == ';') ++cursor;
    char* end = nullptr;
    errno = 0;
    const double value = std::strtod(cursor, &end);
    if (end == cursor || errno == ERANGE || !std::isfinite(value)) return false;
    // The number must end at a separator, so "12abc" is not a coordinate.
    if (*end != '\0' && *end != ' ' && *end != '\t' && *end != ',' && *end != ';' && *end != '\r') {
      return false;
    }
    (*point)[i] = value;
    cursor = end;
  }
  return true;
}

bool IsPointListFile(const std::filesystem::path& path) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return extension == ".txt" || extension == ".asc" || extension == ".xyz" || extension == ".csv";
}

}  // namespace

std::vector<Eigen::Vector3d> ReadPointList(const std::string& path) {
  std::ifstream in = OpenInputFile(path, "point list");
  SIGHTMAP_CHECK(in.is_open(), "cannot read point list " << path << ": check that it exists");
  std::vector<Eigen::Vector3d> points;
  // A header before the points and a footer after them are skipped; a line that cannot be read
  // between two points is a damaged file, refused rather than imported without that point.
  std::string line;
  std::string unread;  // the first unreadable line after a point, while no point has followed
  int unread_number = 0;
  for (int line_number = 1; std::getline(in, line); ++line_number) {
    Eigen::Vector3d point;
    if (ParsePoint(line, &point)) {
      if (unread_number > 0) {
        ThrowMalformedLine(path, unread_number, unread, "'x y z' or 'x,y,z' (a point)");
      }
      points.push_back(point);
      continue;
    }
    const size_t first = line.find_first_not_of(" \t\r");
    const bool blank_or_comment =
        first == std::string::npos || line[first] == '#' || line.compare(first, 2, "//") == 0;
    if (!points.empty() && !blank_or_comment && unread_number == 0) {
      unread = line;
      unread_number = line_number;
    }
  }
  SIGHTMAP_CHECK(!points.empty(), "point list " << path
                                                << " holds no point: expected one 'x y z' or "
                                                   "'x,y,z' per line");
  return points;
}

void WritePointList(const std::string& path, const std::vector<Eigen::Vector3d>& points) {
  AtomicFile file(path);
  file.out() << std::fixed << std::setprecision(6);
  for (const Eigen::Vector3d& p : points) {
    file.out() << p.x() << " " << p.y() << " " << p.z() << "\n";
  }
  file.Commit();
}

std::string LabelFileName(const std::string& label_name) {
  std::string stem = label_name;
  for (char& c : stem) {
    if (c == '/' || c == '\\' || c == '\0') c = '_';
  }
  if (stem == "." || stem == "..") stem = "_" + stem;
  return stem + ".txt";
}

int ExportLabels(const Model& model, const std::string& dir) {
  // Every file name is settled before anything is written, so a collision writes nothing.
  const std::vector<LabelRecord> labels = model.Labels();
  std::map<std::string, std::string> written;  // file name -> label, to refuse collisions
  std::vector<std::string> file_names;         // per label
  for (const LabelRecord& label : labels) {
    file_names.push_back(LabelFileName(label.name));
    const std::string& name = file_names.back();
    SIGHTMAP_CHECK(written.emplace(name, label.name).second,
                   "labels '" << written[name] << "' and '" << label.name << "' would both be "
                              << name << ": rename one of them; nothing was written");
  }
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(dir, ec);
  SIGHTMAP_CHECK(!ec, "cannot create " << dir << ": " << ec.message());
  const fs::path folder(dir);
  // A target that is not a file (a folder, a socket) cannot be replaced: refused before writing.
  for (const std::string& name : file_names) {
    const fs::path target = folder / name;
    const fs::file_status status = fs::status(target, ec);
    SIGHTMAP_CHECK(!fs::exists(status) || fs::is_regular_file(status),
                   "cannot write label file " << target.string()
                                              << ": it is a folder or not a file; move it away "
                                                 "(nothing was written)");
  }
  // Each file goes to a hidden temporary first and all are renamed at the end, the files they
  // replace kept aside until every rename is done: a failure at any step (a full disk, a target
  // that turned into a folder meanwhile) puts the folder back as it was.
  struct Staged {
    fs::path temporary;
    fs::path target;
    fs::path previous;  // the file `target` replaces, kept aside; empty when there was none
    bool renamed = false;
  };
  std::vector<Staged> staged;
  std::string failed = dir;  // the file being written or renamed when something fails
  try {
    for (size_t i = 0; i < labels.size(); ++i) {
      staged.push_back({folder / ("." + file_names[i] + ".partial"), folder / file_names[i], {}});
      failed = staged.back().target.string();
      std::vector<Eigen::Vector3d> points;
      for (const LabelPoint& point : labels[i].points) points.push_back(point.world);
      WritePointList(staged.back().temporary.string(), points);
    }
    for (Staged& file : staged) {
      failed = file.target.string();
      if (fs::exists(file.target)) {
        file.previous = folder / ("." + file.target.filename().string() + ".previous");
        fs::rename(file.target, file.previous);
      }
      fs::rename(file.temporary, file.target);
      file.renamed = true;
    }
    SyncFolder(dir);  // the renames, durable together
  } catch (const std::exception& e) {
    // Back as it was: the new files removed, the replaced ones renamed back, temporaries gone.
    for (const Staged& file : staged) {
      if (file.renamed) fs::remove(file.target, ec);
      if (!file.previous.empty()) fs::rename(file.previous, file.target, ec);
      fs::remove(file.temporary, ec);
    }
    const auto* filesystem_error = dynamic_cast<const fs::filesystem_error*>(&e);
    SIGHTMAP_THROW(Error, "cannot write label file "
                              << failed << ": "
                              << (filesystem_error ? filesystem_error->code().message() : e.what())
                              << " (nothing was written)");
  }
  for (const Staged& file : staged) {
    if (!file.previous.empty()) fs::remove(file.previous, ec);
  }
  return static_cast<int>(labels.size());
}

int ImportLabels(Model& model, const std::string& dir, const std::string& type) {
  std::error_code ec;
  SIGHTMAP_CHECK(std::filesystem::is_directory(dir, ec),
                 "cannot import labels from " << dir << ": not a folder");
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.is_regular_file() && IsPointListFile(entry.path())) files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  // Read every file before writing any label, so a bad file changes nothing.
  std::vector<LabelRecord> labels;
  for (const std::filesystem::path& file : files) {
    LabelRecord label;
    label.name = file.stem().string();
    label.type = type;
    for (const Eigen::Vector3d& world : ReadPointList(file.string())) {
      LabelPoint point;
      point.world = world;
      point.source = LabelPointSource::kImportedFile;
      point.file = file.filename().string();
      label.points.push_back(point);
    }
    labels.push_back(std::move(label));
  }
  for (LabelRecord& label : labels) {
    if (std::optional<LabelRecord> existing = model.FindLabel(label.name)) {
      label.id = existing->id;
      label.type = existing->type;
      model.UpdateLabel(label);
    } else {
      model.AddLabel(label);
    }
  }
  return static_cast<int>(labels.size());
}

}  // namespace sightmap::store
