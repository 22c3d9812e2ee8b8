#include "cli/web_assets.h"

#include <string>
#include <utility>
#include <vector>

namespace sightmap::cli {

// Generated from cli/web/ by cmake/EmbedFiles.cmake: (file name, bytes).
const std::vector<std::pair<std::string_view, std::string_view>>& EmbeddedFiles();

namespace {

std::string_view ContentType(std::string_view name) {
  auto ends_with = [name](std::string_view suffix) {
    return name.size() >= suffix.size() && name.substr(name.size() - suffix.size()) == suffix;
  };
  if (ends_with(".html")) return "text/html; charset=utf-8";
  if (ends_with(".css")) return "text/css; charset=utf-8";
  if (ends_with(".js")) return "text/javascript; charset=utf-8";
  if (ends_with(".svg")) return "image/svg+xml";
  return "application/octet-stream";
}

}  // namespace

std::optional<WebAsset> FindWebAsset(std::string_view url_path) {
  std::string_view name;
  if (url_path == "/" || url_path == "/index.html") {
    name = "phone.html";
  } else if (url_path == "/label" || url_path == "/label/") {
    name = "label.html";
  } else if (url_path.substr(0, 8) == "/static/") {
    name = url_path.substr(8);
    // Pages are reached by their routes only.
    if (name.find(".html") != std::string_view::npos) return std::nullopt;
  } else {
    return std::nullopt;
  }
  for (const auto& [file, bytes] : EmbeddedFiles()) {
    if (file == name) return WebAsset{ContentType(file), bytes};
  }
  return std::nullopt;
}

}  // namespace sightmap::cli
