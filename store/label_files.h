// Appliance labels as CloudCompare point lists (the paper's format): one text file per appliance,
// named after it, one point per line as `x y z` or `x,y,z`; further columns are ignored.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "store/model.h"

namespace sightmap::store {

// Points of one file; lines that do not start with three numbers (headers, comments, a footer)
// are skipped. Throws Error when the file cannot be read, holds no point, or has a line that
// cannot be read between two points (naming it).
std::vector<Eigen::Vector3d> ReadPointList(const std::string& path);
// One `x y z` line per point, in metres with micrometre precision.
void WritePointList(const std::string& path, const std::vector<Eigen::Vector3d>& points);

// The file name a label is written to: its name with path separators replaced, plus ".txt".
std::string LabelFileName(const std::string& label_name);

// Writes every label of the model to DIR/<name>.txt (DIR is created); returns how many.
int ExportLabels(const Model& model, const std::string& dir);

// Reads every *.txt, *.asc, *.xyz and *.csv file of DIR as one label named after the file (its
// stem); an existing label of that name gets the file's points, a new one gets `type`. All labels
// are written, or none when a file is bad. Returns how many.
int ImportLabels(Model& model, const std::string& dir, const std::string& type = "appliance");

}  // namespace sightmap::store
