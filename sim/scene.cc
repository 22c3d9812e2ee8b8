#include "sim/scene.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/rotation.h"
#include "sim/random.h"

namespace sightmap::sim {
namespace {

using nlohmann::json;

Eigen::Vector3d ReadVector3(const json& j, const std::string& what) {
  SIGHTMAP_CHECK(j.is_array() && j.size() == 3, what << " must be an array of 3 numbers");
  return Eigen::Vector3d(j[0].get<double>(), j[1].get<double>(), j[2].get<double>());
}

Eigen::Vector2d ReadVector2(const json& j, const std::string& what) {
  SIGHTMAP_CHECK(j.is_array() && j.size() == 2, what << " must be an array of 2 numbers");
  return Eigen::Vector2d(j[0].get<double>(), j[1].get<double>());
}

SceneBox ReadBox(const json& j, const Scene& scene, const std::string& where) {
  SceneBox box;
  box.name = j.value("name", std::string());
  const std::string what = where + " box '" + box.name + "'";
  SIGHTMAP_CHECK(j.contains("center") && j.contains("size") && j.contains("material"),
                 what << " needs center, size and material");
  box.center = ReadVector3(j["center"], what + " center");
  box.size = ReadVector3(j["size"], what + " size");
  SIGHTMAP_CHECK(box.size.minCoeff() > 0.0, what << " has a non-positive size");
  box.yaw_rad = DegToRad(j.value("yaw_deg", 0.0));
  box.material = j["material"].get<std::string>();
  SIGHTMAP_CHECK(scene.materials.count(box.material) == 1,
                 what << " uses material '" << box.material << "' which \"materials\" lacks");
  box.group = j.value("group", std::string());
  return box;
}

Eigen::Matrix3d YawRotation(double yaw_rad) {
  return Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

}  // namespace

std::optional<double> SceneBox::Intersect(const Eigen::Vector3d& origin,
                                          const Eigen::Vector3d& direction) const {
  // Slab test in the box's own frame.
  const Eigen::Matrix3d box_from_world = YawRotation(yaw_rad).transpose();
  const Eigen::Vector3d o = box_from_world * (origin - center);
  const Eigen::Vector3d d = box_from_world * direction;
  const Eigen::Vector3d h = 0.5 * size;
  double t_min = 0.0;
  double t_max = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 3; ++i) {
    if (std::abs(d[i]) < 1e-12) {
      if (std::abs(o[i]) > h[i]) return std::nullopt;
      continue;
    }
    double t0 = (-h[i] - o[i]) / d[i];
    double t1 = (h[i] - o[i]) / d[i];
    if (t0 > t1) std::swap(t0, t1);
    t_min = std::max(t_min, t0);
    t_max = std::min(t_max, t1);
    if (t_min > t_max) return std::nullopt;
  }
  return t_min;
}

bool SceneBox::Contains(const Eigen::Vector3d& point, double margin_m) const {
  const Eigen::Vector3d p = YawRotation(yaw_rad).transpose() * (point - center);
  const Eigen::Vector3d h = 0.5 * size + Eigen::Vector3d::Constant(margin_m);
  return std::abs(p.x()) <= h.x() && std::abs(p.y()) <= h.y() && std::abs(p.z()) <= h.z();
}

bool Room::Contains(const Eigen::Vector2d& p, double margin_m) const {
  return p.x() >= min.x() + margin_m && p.x() <= max.x() - margin_m &&
         p.y() >= min.y() + margin_m && p.y() <= max.y() - margin_m;
}

const Room* Scene::RoomAt(const Eigen::Vector2d& p) const {
  for (const Room& room : rooms) {
    if (room.Contains(p)) return &room;
  }
  return nullptr;
}

std::optional<std::pair<double, std::string>> Scene::Raycast(const Eigen::Vector3d& origin,
                                                             const Eigen::Vector3d& direction,
                                                             double max_distance_m,
                                                             int ignore_appliance) const {
  std::optional<std::pair<double, std::string>> best;
  auto consider = [&](const SceneBox& box) {
    const std::optional<double> t = box.Intersect(origin, direction);
    if (t && *t <= max_distance_m && (!best || *t < best->first)) best = {{*t, box.name}};
  };
  for (const SceneBox& box : boxes) consider(box);
  for (const Appliance& appliance : appliances) {
    if (appliance.id == ignore_appliance) continue;
    for (const SceneBox& box : appliance.boxes) consider(box);
  }
  return best;
}

bool Scene::IsFree(const Eigen::Vector3d& point, double margin_m) const {
  for (const SceneBox& box : boxes) {
    if (box.Contains(point, margin_m)) return false;
  }
  for (const Appliance& appliance : appliances) {
    for (const SceneBox& box : appliance.boxes) {
      if (box.Contains(point, margin_m)) return false;
    }
  }
  return true;
}

Eigen::AlignedBox2d Scene::FloorBounds() const {
  Eigen::AlignedBox2d bounds;
  for (const SceneBox& box : boxes) {
    const double r = 0.5 * box.size.head<2>().norm();
    bounds.extend(box.center.head<2>() - Eigen::Vector2d(r, r));
    bounds.extend(box.center.head<2>() + Eigen::Vector2d(r, r));
  }
  for (const Room& room : rooms) {
    bounds.extend(room.min);
    bounds.extend(room.max);
  }
  return bounds;
}

Scene ParseScene(const std::string& json_text, const std::string& origin) {
  json j;
  try {
    j = json::parse(json_text);
  } catch (const json::exception& e) {
    SIGHTMAP_THROW(Error, "scene " << origin << " is not valid JSON: " << e.what());
  }
  Scene scene;
  scene.source = origin;
  try {
    scene.name = j.value("name", std::string("unnamed"));
    scene.ceiling_height_m = j.value("ceiling_height_m", 2.8);
    const json textures = j.value("textures", json::object());  // items() must not outlive it
    for (const auto& [key, value] : textures.items()) {
      const std::string file = value.get<std::string>();
      SIGHTMAP_CHECK(file.rfind(kProceduralPrefix, 0) != 0 ||
                         !ProceduralTexture(file.substr(std::strlen(kProceduralPrefix))).empty(),
                     "scene " << origin << ": texture '" << key << "' names an unknown " << file
                              << " (procedural:ceiling_tile or procedural:vent)");
      scene.texture_files[key] = file;
    }
    SIGHTMAP_CHECK(j.contains("materials"), "scene " << origin << " has no \"materials\"");
    for (const auto& [key, value] : j["materials"].items()) {
      SceneMaterial material;
      if (value.contains("color")) {
        material.color_rgb =
            ReadVector3(value["color"], "material " + key + " color").cast<float>();
      }
      material.texture = value.value("texture", std::string());
      SIGHTMAP_CHECK(material.texture.empty() || scene.texture_files.count(material.texture) == 1,
                     "scene " << origin << ": material '" << key << "' uses texture '"
                              << material.texture << "' which \"textures\" lacks");
      material.scale_m = value.value("scale_m", 0.0f);
      material.contrast = value.value("contrast", 1.0f);
      SIGHTMAP_CHECK(material.contrast > 0.0f && material.contrast <= 1.0f,
                     "scene " << origin << ": material '" << key << "' needs contrast in (0, 1]");
      material.no_depth = value.value("no_depth", false);
      material.unlit = value.value("unlit", false);
      scene.materials[key] = material;
    }
    for (const json& box : j.value("boxes", json::array())) {
      scene.boxes.push_back(ReadBox(box, scene, "scene " + origin + ":"));
    }
    int next_id = 1;
    for (const json& a : j.value("appliances", json::array())) {
      Appliance appliance;
      appliance.id = next_id++;
      appliance.name = a.at("name").get<std::string>();
      appliance.type = a.at("type").get<std::string>();
      for (const json& p : a.at("points")) {
        appliance.points.push_back(ReadVector3(p, "appliance " + appliance.name + " point"));
      }
      SIGHTMAP_CHECK(!appliance.points.empty(),
                     "appliance " << appliance.name << " needs at least one point");
      for (const json& box : a.value("boxes", json::array())) {
        appliance.boxes.push_back(
            ReadBox(box, scene, "scene " + origin + ": appliance " + appliance.name));
      }
      scene.appliances.push_back(std::move(appliance));
    }
    for (const json& r : j.value("rooms", json::array())) {
      Room room;
      room.name = r.at("name").get<std::string>();
      room.min = ReadVector2(r.at("min"), "room min");
      room.max = ReadVector2(r.at("max"), "room max");
      scene.rooms.push_back(room);
    }
    for (const json& p : j.value("tour", json::array())) {
      scene.tour.push_back(ReadVector2(p, "tour point"));
    }
  } catch (const json::exception& e) {
    SIGHTMAP_THROW(Error, "scene " << origin << " has a malformed field: " << e.what());
  }
  SIGHTMAP_CHECK(scene.tour.size() >= 3,
                 "scene " << origin << " needs a \"tour\" of at least 3 floor points to walk");
  SIGHTMAP_CHECK(!scene.rooms.empty(), "scene " << origin << " needs at least one room");
  return scene;
}

Scene LoadScene(const std::string& name_or_file) {
  if (name_or_file == "office") return ParseScene(OfficeSceneJson(), "embedded:office");
  std::ifstream in(name_or_file);
  SIGHTMAP_CHECK(in.good(), "cannot read scene file " << name_or_file
                                                      << ": give 'office' (the embedded scene) or "
                                                         "the path of a scene JSON file");
  std::stringstream text;
  text << in.rdbuf();
  return ParseScene(text.str(), name_or_file);
}

Scene ApplySession(const Scene& scene, int session, uint64_t seed) {
  Scene moved = scene;
  if (session == 1) return moved;
  std::mt19937_64 rng(MixSeed(seed, 0x5e55'1000ULL + static_cast<uint64_t>(session)));
  std::map<std::string, std::pair<Eigen::Vector2d, double>> moves;  // group -> (shift, turn)
  for (SceneBox& box : moved.boxes) {
    if (box.group.empty()) continue;
    if (moves.count(box.group) == 0) {
      const double angle = UniformReal(rng, -kPi, kPi);
      const double distance = UniformReal(rng, 0.0, 0.5);
      const double turn = UniformReal(rng, -0.7, 0.7);
      moves[box.group] = {distance * Eigen::Vector2d(std::cos(angle), std::sin(angle)), turn};
    }
    // Turn the group about its first box's vertical axis so the parts stay together.
    const auto& [shift, turn] = moves[box.group];
    const SceneBox* pivot = nullptr;
    for (const SceneBox& b : scene.boxes) {
      if (b.group == box.group) {
        pivot = &b;
        break;
      }
    }
    const Eigen::Vector3d offset = box.center - pivot->center;
    box.center = pivot->center + YawRotation(turn) * offset;
    box.center.head<2>() += shift;
    box.yaw_rad += turn;
  }
  return moved;
}

std::string TextureDirectory() {
  const char* env = std::getenv("SIGHTMAP_TEXTURE_DIR");
  if (env != nullptr && env[0] != '\0') return env;
  return "/usr/share/doc/opencv-doc/examples/data";
}

namespace {

// An acoustic ceiling tile as every tile of a suspended ceiling shows it (one repeat of the grid):
// a light grey board with short dark fissures and pinholes, framed by the T-bar grid's strip.
// Fixed seed: every tile, every run, the same pattern, as in a real grid.
cv::Mat CeilingTileTexture() {
  constexpr int kSize = 256;
  cv::Mat tile(kSize, kSize, CV_8UC3, cv::Scalar::all(236));
  cv::RNG rng(0x7113);
  for (int i = 0; i < 220; ++i) {
    const cv::Point a(rng.uniform(10, kSize - 10), rng.uniform(10, kSize - 10));
    const double angle = rng.uniform(0.0, CV_PI);
    const int length = rng.uniform(3, 14);
    const cv::Point b(a.x + static_cast<int>(length * std::cos(angle)),
                      a.y + static_cast<int>(length * std::sin(angle)));
    const int shade = rng.uniform(150, 205);
    cv::line(tile, a, b, cv::Scalar::all(shade), 1, cv::LINE_AA);
  }
  for (int i = 0; i < 400; ++i) {
    const cv::Point at(rng.uniform(8, kSize - 8), rng.uniform(8, kSize - 8));
    cv::circle(tile, at, 1, cv::Scalar::all(rng.uniform(170, 215)), cv::FILLED);
  }
  // The T-bar: 24 mm of a 600 mm tile, half on each edge of the repeat.
  const int bar = std::max(1, kSize * 12 / 600);
  const cv::Scalar metal(205, 208, 210);
  const cv::Scalar shadow(150, 150, 152);
  cv::rectangle(tile, cv::Rect(0, 0, kSize, bar), metal, cv::FILLED);
  cv::rectangle(tile, cv::Rect(0, kSize - bar, kSize, bar), metal, cv::FILLED);
  cv::rectangle(tile, cv::Rect(0, 0, bar, kSize), metal, cv::FILLED);
  cv::rectangle(tile, cv::Rect(kSize - bar, 0, bar, kSize), metal, cv::FILLED);
  cv::rectangle(tile, cv::Rect(bar, bar, kSize - 2 * bar, kSize - 2 * bar), shadow, 1);
  return tile;
}

// A supply-air diffuser's face: nested square louvres round a square centre.
cv::Mat VentTexture() {
  constexpr int kSize = 256;
  cv::Mat vent(kSize, kSize, CV_8UC3, cv::Scalar::all(225));
  for (int ring = 0; ring < 6; ++ring) {
    const int inset = 10 + ring * 18;
    cv::rectangle(vent, cv::Rect(inset, inset, kSize - 2 * inset, kSize - 2 * inset),
                  cv::Scalar::all(ring % 2 == 0 ? 95 : 180), 5);
  }
  cv::rectangle(vent, cv::Rect(0, 0, kSize, kSize), cv::Scalar::all(160), 4);
  return vent;
}

}  // namespace

cv::Mat ProceduralTexture(const std::string& name) {
  if (name == "ceiling_tile") return CeilingTileTexture();
  if (name == "vent") return VentTexture();
  return cv::Mat();
}

void AddSceneToRenderer(const Scene& scene, render::MeshRenderer* renderer) {
  const std::filesystem::path scene_dir = std::filesystem::path(scene.source).has_parent_path()
                                              ? std::filesystem::path(scene.source).parent_path()
                                              : std::filesystem::path(".");
  std::map<std::string, cv::Mat> images;
  for (const auto& [key, file] : scene.texture_files) {
    if (file.rfind(kProceduralPrefix, 0) == 0) {
      images[key] = ProceduralTexture(file.substr(std::strlen(kProceduralPrefix)));
      continue;
    }
    std::filesystem::path path = file;
    if (path.is_relative()) {
      const std::filesystem::path beside = scene_dir / file;
      path = (scene.source.rfind("embedded:", 0) != 0 && std::filesystem::exists(beside))
                 ? beside
                 : std::filesystem::path(TextureDirectory()) / file;
    }
    cv::Mat image = cv::imread(path.string(), cv::IMREAD_COLOR);
    SIGHTMAP_CHECK(!image.empty(), "cannot read texture "
                                       << path.string() << " (scene " << scene.source
                                       << "): install the sample photographs with 'apt-get "
                                          "install opencv-doc' or set SIGHTMAP_TEXTURE_DIR");
    // 512 px is sharper than any poster gets in a 640x480 frame, and keeps uploads quick.
    const double scale = 512.0 / std::max(image.cols, image.rows);
    if (scale < 1.0) cv::resize(image, image, cv::Size(), scale, scale, cv::INTER_AREA);
    images[key] = image;
  }
  // One GL texture per (image, contrast) pair in use.
  std::map<std::pair<std::string, float>, int> handles;
  auto handle_of = [&](const SceneMaterial& m) {
    const auto key = std::make_pair(m.texture, m.contrast);
    auto it = handles.find(key);
    if (it != handles.end()) return it->second;
    cv::Mat image = images.at(m.texture);
    if (m.contrast < 1.0f) {
      const cv::Scalar mean = cv::mean(image);
      image.convertTo(image, -1, m.contrast, 0.0);
      // Centred on a light grey, so paint stays the material's colour and only the detail remains.
      cv::add(image, cv::Scalar::all(230.0) - mean * m.contrast, image);
    }
    return handles[key] = renderer->AddTexture(image);
  };
  // Boxes sharing a material and an appliance ID go into one mesh: a furnished floor has a
  // thousand boxes (books, radiator ribs, notes) but a few dozen materials, and the renderer
  // pays per mesh (state changes and a draw call each).
  std::map<std::pair<int, std::string>, render::TriangleMesh> merged;
  auto add_box = [&](const SceneBox& box, int id) {
    const SceneMaterial& m = scene.materials.at(box.material);
    render::Material material;
    material.color_rgb = m.color_rgb;
    material.texture = m.texture.empty() ? -1 : handle_of(m);
    material.texture_scale_m = m.scale_m;
    material.no_depth = m.no_depth;
    material.unlit = m.unlit;
    const render::TriangleMesh mesh =
        render::MakeBox(box.center.cast<float>(), box.size.cast<float>(),
                        static_cast<float>(box.yaw_rad), material, id);
    auto [it, inserted] = merged.try_emplace({id, box.material}, mesh);
    if (inserted) return;
    render::TriangleMesh& all = it->second;
    all.positions.insert(all.positions.end(), mesh.positions.begin(), mesh.positions.end());
    all.normals.insert(all.normals.end(), mesh.normals.begin(), mesh.normals.end());
    all.uvs.insert(all.uvs.end(), mesh.uvs.begin(), mesh.uvs.end());
  };
  for (const SceneBox& box : scene.boxes) add_box(box, 0);
  for (const Appliance& appliance : scene.appliances) {
    for (const SceneBox& box : appliance.boxes) add_box(box, appliance.id);
  }
  for (auto& [key, mesh] : merged) renderer->AddMesh(std::move(mesh));
}

double ViewScore(const Scene& scene, const Eigen::Vector3d& eye, double yaw,
                 const std::set<std::string>* also_bare) {
  // Rows 11 deg up, level and 14 deg down: the image's upper, middle and lower part.
  double score = 0.0;
  std::vector<std::string> things;
  for (const double down : {-0.2, 0.0, 0.25}) {
    for (int k = -4; k <= 4; ++k) {
      const double a = yaw + k * 0.12;
      const Eigen::Vector3d dir(std::cos(a) * std::cos(down), std::sin(a) * std::cos(down),
                                -std::sin(down));
      // One ray to the street: the room's things count within 4.3 m, and a view out of a window
      // (the street 25-60 m away) as bare as the wall around it.
      const auto hit = scene.Raycast(eye, dir, 60.0);
      if (!hit) continue;
      const std::string& name = hit->second;
      if (hit->first > 4.3) {
        if (name.rfind("outside", 0) == 0) score += 0.25;
        continue;
      }
      if (hit->first < 0.8) continue;
      const bool bare = name.rfind("wall", 0) == 0 || name.rfind("window", 0) == 0 ||
                        name.rfind("skirting", 0) == 0 || name.rfind("floor", 0) == 0 ||
                        (also_bare != nullptr && also_bare->count(name) > 0);
      score += bare ? 0.25 : 0.5;
      if (!bare && std::find(things.begin(), things.end(), name) == things.end()) {
        things.push_back(name);
        score += 1.0;
      }
    }
  }
  return score;
}

std::set<std::string> PlainBoxNames(const Scene& scene) {
  std::set<std::string> names;
  auto add = [&](const SceneBox& box) {
    const auto material = scene.materials.find(box.material);
    if (material == scene.materials.end() || material->second.texture.empty()) {
      names.insert(box.name);
    }
  };
  for (const SceneBox& box : scene.boxes) add(box);
  for (const Appliance& appliance : scene.appliances) {
    for (const SceneBox& box : appliance.boxes) add(box);
  }
  return names;
}

}  // namespace sightmap::sim
