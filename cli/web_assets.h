// The web pages `sightmap serve` carries in its binary (cli/web/, embedded at build time): plain
// HTML, CSS and script, no framework and nothing fetched from elsewhere, so a phone on the
// building's network needs only this server.
//
//   GET /                 the phone page: take a photo, see the appliances in it
//   GET /label            the labelling page: click a keyframe pixel to label an appliance
//   GET /static/NAME      their style sheet and scripts
#pragma once

#include <optional>
#include <string_view>

namespace sightmap::cli {

struct WebAsset {
  std::string_view content_type;
  std::string_view bytes;
};

// The asset served at `url_path`, or nothing.
std::optional<WebAsset> FindWebAsset(std::string_view url_path);

}  // namespace sightmap::cli
