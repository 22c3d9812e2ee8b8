// The synthetic building's scene: boxes with materials (walls, floors, furniture, posters),
// appliances (named, typed, with 3D centre points and their own boxes), rooms and a walking tour.
//
// Scene files are JSON (see office_scene.json, the embedded default, and
// tools/make_office_scene.py which writes it):
//   {"name": "...", "ceiling_height_m": 2.8,
//    "textures":  {"graf": "graf1.png", ...},          // file names: absolute, relative to the
//                                                      // scene file, or in the texture folder;
//                                                      // "procedural:ceiling_tile" or
//                                                      // "procedural:vent" are drawn
//    "materials": {"wall": {"color": [r, g, b],        // [0, 1]
//                           "texture": "graf",         // optional, a key of "textures"
//                           "scale_m": 1.0,            // metres per texture repeat; 0 = stretch
//                           "contrast": 1.0,           // texture contrast kept, (0, 1]: faint
//                                                      // paint and plaster on walls
//                           "no_depth": false,         // glass / glossy screens: no IR return
//                           "unlit": false}},          // emissive (lights, screens)
//    "boxes": [{"name": "...", "center": [x, y, z], "size": [sx, sy, sz], "yaw_deg": 0,
//               "material": "wall", "group": "chair_1"}],   // a group moves between sessions
//    "appliances": [{"name": "monitor_1", "type": "monitor", "points": [[x, y, z]],
//                    "boxes": [...]}],
//    "rooms": [{"name": "lab", "min": [x, y], "max": [x, y]}],   // floor-plan rectangles
//    "tour": [[x, y], ...]}                                      // a closed walk on the floor
// World frame: x, y on the floor, z up, metres. A box's yaw turns it about z around its centre.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "render/mesh_renderer.h"

namespace sightmap::sim {

struct SceneMaterial {
  Eigen::Vector3f color_rgb = Eigen::Vector3f(0.8f, 0.8f, 0.8f);
  std::string texture;  // a key of Scene::texture_files, empty = plain colour
  float scale_m = 0.0f;
  float contrast = 1.0f;  // the texture blended towards its mean colour, (0, 1]
  bool no_depth = false;
  bool unlit = false;
};

struct SceneBox {
  std::string name;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  // [m]
  Eigen::Vector3d size = Eigen::Vector3d::Ones();    // [m], along the box's own axes
  double yaw_rad = 0.0;
  std::string material;
  std::string group;  // boxes sharing a group move together between sessions (chairs)

  // Distance along the ray origin + t * direction (t >= 0) to the box, if it is hit.
  std::optional<double> Intersect(const Eigen::Vector3d& origin,
                                  const Eigen::Vector3d& direction) const;
  bool Contains(const Eigen::Vector3d& point, double margin_m) const;
};

struct Appliance {
  int id = 0;  // 1-based, the value in the ID buffer
  std::string name;
  std::string type;  // lamp, monitor, projector, screen, thermostat, light_switch, tv, printer,
                     // ceiling_light (free text for user scenes)
  std::vector<Eigen::Vector3d> points;  // labelled centre point(s) [m]
  std::vector<SceneBox> boxes;
};

struct Room {
  std::string name;
  Eigen::Vector2d min = Eigen::Vector2d::Zero();
  Eigen::Vector2d max = Eigen::Vector2d::Zero();
  bool Contains(const Eigen::Vector2d& p, double margin_m = 0.0) const;
};

struct Scene {
  std::string name;
  std::string source;  // "embedded" or the file path, for messages
  double ceiling_height_m = 2.8;
  std::map<std::string, std::string> texture_files;
  std::map<std::string, SceneMaterial> materials;
  std::vector<SceneBox> boxes;
  std::vector<Appliance> appliances;
  std::vector<Room> rooms;
  std::vector<Eigen::Vector2d> tour;

  // The room containing a floor point, or nullptr.
  const Room* RoomAt(const Eigen::Vector2d& p) const;
  // The nearest box (scene or appliance) hit by the ray before max_distance_m; `ignore_appliance`
  // skips that appliance's own boxes. Returns the hit distance and the box's name.
  std::optional<std::pair<double, std::string>> Raycast(const Eigen::Vector3d& origin,
                                                        const Eigen::Vector3d& direction,
                                                        double max_distance_m,
                                                        int ignore_appliance = 0) const;
  // True when the point is at least margin_m outside every box.
  bool IsFree(const Eigen::Vector3d& point, double margin_m) const;
  // Floor-plan bounds of all boxes [m].
  Eigen::AlignedBox2d FloorBounds() const;
};

// How much of a view towards `yaw` (from `eye`, the camera about level) the sensor measures and
// how many things it shows: nine rays across the colour camera's 62 deg at three heights of the
// image, each ending on a surface 0.8-4.3 m away counting 0.5 on furniture, posters and
// appliances and 0.25 on bare walls, floor and windows, each distinct thing met 1 more. People
// (and a mapping robot) look at things; a view of bare wall is one a tracker loses. `also_bare`
// names further boxes that count as bare (PlainBoxNames: a blank projection screen holds no
// more features than a wall).
double ViewScore(const Scene& scene, const Eigen::Vector3d& eye, double yaw,
                 const std::set<std::string>* also_bare = nullptr);

// Names of the boxes (scene and appliance) whose material has no texture.
std::set<std::string> PlainBoxNames(const Scene& scene);

// The JSON text of the embedded default scene "office".
const char* OfficeSceneJson();

// Parses a scene; `origin` names it in errors and is the folder relative texture files are
// looked up in first. Throws sightmap::Error naming the field that is wrong.
Scene ParseScene(const std::string& json_text, const std::string& origin);

// "office" -> the embedded scene; anything else is read as a scene file.
Scene LoadScene(const std::string& name_or_file);

// The same building on another day: session 1 is the scene as written; other sessions move each
// box group (chairs) by up to 0.5 m and turn it by up to 40 degrees, reproducibly from the
// session number and seed.
Scene ApplySession(const Scene& scene, int session, uint64_t seed);

// Folder of the opencv-doc sample photographs used as textures ($SIGHTMAP_TEXTURE_DIR overrides).
std::string TextureDirectory();

// Textures a scene names as "procedural:NAME" are drawn, not read: "ceiling_tile" (one 600 mm
// acoustic tile of a suspended ceiling with its T-bar, the same on every tile, as in a real grid)
// and "vent" (a square diffuser's louvres). Empty for another name.
inline constexpr char kProceduralPrefix[] = "procedural:";
cv::Mat ProceduralTexture(const std::string& name);

// Loads the textures (cached by the renderer's lifetime) and adds every box as a mesh; appliance
// boxes carry their appliance ID. Throws sightmap::Error naming a missing texture file and the
// package that provides it.
void AddSceneToRenderer(const Scene& scene, render::MeshRenderer* renderer);

}  // namespace sightmap::sim
