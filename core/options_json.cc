#include "core/options_json.h"

#include <algorithm>
#include <vector>

namespace sightmap {
namespace {

std::vector<std::string> SplitFieldList(const char* fields) {
  std::vector<std::string> names;
  std::string name;
  for (const char* c = fields; *c != '\0'; ++c) {
    if (*c == ',') {
      names.push_back(name);
      name.clear();
    } else if (*c != ' ' && *c != '\n' && *c != '\t') {
      name += *c;
    }
  }
  if (!name.empty()) names.push_back(name);
  return names;
}

size_t EditDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

}  // namespace

OptionsJsonError::OptionsJsonError(std::string path, std::string reason)
    : InvalidArgument(path.empty() ? reason : path + ": " + reason),
      path_(std::move(path)),
      reason_(std::move(reason)) {}

namespace options_json {

std::string PlainMessage(const nlohmann::json::exception& error) {
  const std::string message = error.what();
  const size_t end = message.rfind("] ", message.find(' '));
  return message.rfind("[json.exception.", 0) == 0 && end != std::string::npos
             ? message.substr(end + 2)
             : message;
}

void CheckKeys(const nlohmann::json& json, const char* fields) {
  if (!json.is_object()) throw OptionsJsonError("", "must be an object ({...})");
  const std::vector<std::string> names = SplitFieldList(fields);
  for (auto item = json.begin(); item != json.end(); ++item) {
    const std::string& key = item.key();
    if (std::find(names.begin(), names.end(), key) != names.end()) continue;
    std::string reason = "unknown option";
    // A typo is a few letters off; anything further is not worth a guess.
    const auto closest = std::min_element(names.begin(), names.end(),
                                          [&key](const std::string& a, const std::string& b) {
                                            return EditDistance(key, a) < EditDistance(key, b);
                                          });
    if (closest != names.end() &&
        EditDistance(key, *closest) <= std::max<size_t>(2, key.size() / 4)) {
      reason += "; did you mean " + *closest + "?";
    }
    throw OptionsJsonError(key, reason);
  }
}

}  // namespace options_json
}  // namespace sightmap
