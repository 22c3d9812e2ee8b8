// Options structs as JSON: what the model's session row stores, what `--config FILE` reads and
// `--print-config` prints. Each struct's header declares
//
//   void to_json(nlohmann::json& json, const FooOptions& options);
//   void from_json(const nlohmann::json& json, FooOptions& options);
//
// beside the struct (with <nlohmann/json_fwd.hpp>), and its .cc lists the fields once:
//
//   SIGHTMAP_OPTIONS_JSON(FooOptions, width, height, rate_hz, nested)
//
// Reading is strict, because a config file is written by hand: a key the struct does not have, a
// number where a flag is expected or 2.5 for a count is refused with the key's full path
// ("mapper.loop_candidate: unknown option; did you mean loop_candidates?"). A key that is absent
// keeps the value the struct already holds, so a config names only what it changes; ranges are
// left to the struct's Check().
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "core/check.h"

namespace sightmap {

// A value in an options JSON that cannot be read; what() is "<path>: <reason>".
class OptionsJsonError : public InvalidArgument {
 public:
  OptionsJsonError(std::string path, std::string reason);
  const std::string& path() const { return path_; }
  const std::string& reason() const { return reason_; }

 private:
  std::string path_;
  std::string reason_;
};

namespace options_json {

// Throws OptionsJsonError unless `json` is an object whose keys are all among `fields` (the
// stringised field list of SIGHTMAP_OPTIONS_JSON: "width, height, rate_hz").
void CheckKeys(const nlohmann::json& json, const char* fields);

// nlohmann's message without its "[json.exception.type_error.302] " prefix.
std::string PlainMessage(const nlohmann::json::exception& error);

// nlohmann's own conversions truncate 2.5 to 2 and wrap -1 into an unsigned; a config must not.
template <typename T>
void ReadNumber(const nlohmann::json& json, T& value) {
  if constexpr (std::is_same_v<T, bool>) {
    if (!json.is_boolean()) throw OptionsJsonError("", "must be true or false");
    value = json.get<bool>();
  } else if constexpr (std::is_integral_v<T>) {
    if (json.is_number_float()) {
      // 1e300 is written as a whole number but fits no count: say so, not "not whole".
      const double number = json.get<double>();
      const bool whole = std::isfinite(number) && number == std::floor(number);
      if (whole && (number < static_cast<double>(std::numeric_limits<T>::min()) ||
                    number > static_cast<double>(std::numeric_limits<T>::max()))) {
        throw OptionsJsonError("", "is out of range: must be from " +
                                       std::to_string(std::numeric_limits<T>::min()) + " to " +
                                       std::to_string(std::numeric_limits<T>::max()));
      }
    }
    if (!json.is_number_integer()) throw OptionsJsonError("", "must be a whole number");
    if (json.is_number_unsigned()) {
      const uint64_t number = json.get<uint64_t>();
      if (number > static_cast<uint64_t>(std::numeric_limits<T>::max())) {
        throw OptionsJsonError("", "is too large");
      }
      value = static_cast<T>(number);
    } else {
      const int64_t number = json.get<int64_t>();
      if (std::is_unsigned_v<T> && number < 0) throw OptionsJsonError("", "must not be negative");
      if constexpr (std::is_signed_v<T>) {
        if (number < static_cast<int64_t>(std::numeric_limits<T>::min()) ||
            number > static_cast<int64_t>(std::numeric_limits<T>::max())) {
          throw OptionsJsonError("", "is out of range");
        }
      }
      value = static_cast<T>(number);
    }
  } else {
    if (!json.is_number()) throw OptionsJsonError("", "must be a number");
    value = json.get<T>();
  }
}

template <typename T>
struct IsNumberVector : std::false_type {};
template <typename T>
struct IsNumberVector<std::vector<T>> : std::is_arithmetic<T> {};

// Reads json[key] into `value` when present, naming `key` in any error (nested structs prefix
// their own path: "mapper.pose_graph.max_iterations").
template <typename T>
void ReadField(const nlohmann::json& json, const char* key, T& value) {
  const auto it = json.find(key);
  if (it == json.end()) return;
  try {
    if constexpr (std::is_arithmetic_v<T>) {
      ReadNumber(*it, value);
    } else if constexpr (std::is_same_v<T, std::string>) {
      if (!it->is_string()) throw OptionsJsonError("", "must be a string");
      value = it->template get<std::string>();
    } else if constexpr (IsNumberVector<T>::value) {
      if (!it->is_array()) throw OptionsJsonError("", "must be an array of numbers");
      T numbers(it->size());
      for (size_t i = 0; i < numbers.size(); ++i) {
        try {
          ReadNumber((*it)[i], numbers[i]);
        } catch (const OptionsJsonError& e) {
          throw OptionsJsonError("[" + std::to_string(i) + "]", e.reason());
        }
      }
      value = std::move(numbers);
    } else {
      it->get_to(value);
    }
  } catch (const OptionsJsonError& e) {
    const std::string separator = e.path().empty() || e.path().front() == '[' ? "" : ".";
    throw OptionsJsonError(std::string(key) + separator + e.path(), e.reason());
  } catch (const nlohmann::json::exception& e) {
    throw OptionsJsonError(key, PlainMessage(e));
  }
}

// An enum as one of its names (a table `{{Enum::kA, "a"}, ...}` in the enum's .cc); any other
// string is refused with the list of names.
template <typename Enum, size_t N>
void WriteEnum(nlohmann::json& json, Enum value, const std::pair<Enum, const char*> (&names)[N]) {
  json = nullptr;
  for (const auto& [candidate, name] : names) {
    if (candidate == value) json = name;
  }
}
template <typename Enum, size_t N>
void ReadEnum(const nlohmann::json& json, Enum& value,
              const std::pair<Enum, const char*> (&names)[N]) {
  std::string accepted;
  for (const auto& [candidate, name] : names) {
    if (json.is_string() && json.get<std::string>() == name) {
      value = candidate;
      return;
    }
    accepted += (accepted.empty() ? "" : ", ") + std::string(name);
  }
  throw OptionsJsonError("", "must be one of " + accepted);
}

// Reads a whole options struct from `text` (a config file's contents, named `origin` in errors);
// the struct's current values stay where the text is silent.
template <typename Options>
void ParseInto(const std::string& text, const std::string& origin, Options& options) {
  nlohmann::json json;
  try {
    json = nlohmann::json::parse(text, nullptr, true, /*ignore_comments=*/true);
  } catch (const nlohmann::json::exception& e) {  // a parse error, or a number like 1e999
    SIGHTMAP_THROW(InvalidArgument,
                   origin << " is not valid JSON: " << options_json::PlainMessage(e));
  }
  try {
    from_json(json, options);
  } catch (const OptionsJsonError& e) {
    SIGHTMAP_THROW(InvalidArgument, origin << ": " << e.what());
  }
}

}  // namespace options_json
}  // namespace sightmap

// Eigen vectors as JSON arrays ([x, y, z]).
namespace nlohmann {
template <typename Scalar, int Rows>
struct adl_serializer<Eigen::Matrix<Scalar, Rows, 1>> {
  static void to_json(json& json, const Eigen::Matrix<Scalar, Rows, 1>& vector) {
    json = nlohmann::json::array();
    for (int i = 0; i < Rows; ++i) json.push_back(vector[i]);
  }
  static void from_json(const json& json, Eigen::Matrix<Scalar, Rows, 1>& vector) {
    if (!json.is_array() || json.size() != static_cast<size_t>(Rows)) {
      throw ::sightmap::OptionsJsonError(
          "", "must be an array of " + std::to_string(Rows) + " numbers");
    }
    for (int i = 0; i < Rows; ++i) {
      ::sightmap::options_json::ReadNumber(json[static_cast<size_t>(i)], vector[i]);
    }
  }
};
}  // namespace nlohmann

#define SIGHTMAP_OPTIONS_JSON_WRITE_FIELD(field) json[#field] = options.field;
#define SIGHTMAP_OPTIONS_JSON_READ_FIELD(field) \
  ::sightmap::options_json::ReadField(json, #field, options.field);

// Defines to_json and from_json for an options struct from its field names (in the struct's
// namespace, in its .cc).
#define SIGHTMAP_OPTIONS_JSON(Type, ...)                                                      \
  void to_json(nlohmann::json& json, const Type& options) {                                   \
    json = nlohmann::json::object();                                                          \
    NLOHMANN_JSON_EXPAND(NLOHMANN_JSON_PASTE(SIGHTMAP_OPTIONS_JSON_WRITE_FIELD, __VA_ARGS__)) \
  }                                                                                           \
  void from_json(const nlohmann::json& json, Type& options) {                                 \
    ::sightmap::options_json::CheckKeys(json, #__VA_ARGS__);                                  \
    NLOHMANN_JSON_EXPAND(NLOHMANN_JSON_PASTE(SIGHTMAP_OPTIONS_JSON_READ_FIELD, __VA_ARGS__))  \
  }

#define SIGHTMAP_OPTIONS_JSON_UNPAREN(...) __VA_ARGS__
#define SIGHTMAP_OPTIONS_JSON_STRING(...) #__VA_ARGS__
// The same for a struct of more than 63 fields (the most nlohmann's paste macro takes), its fields
// in two parenthesised lists: SIGHTMAP_OPTIONS_JSON_LONG(FooOptions, (a, b, ...), (c, d, ...)).
#define SIGHTMAP_OPTIONS_JSON_LONG(Type, first, second)                                     \
  void to_json(nlohmann::json& json, const Type& options) {                                 \
    json = nlohmann::json::object();                                                        \
    NLOHMANN_JSON_EXPAND(NLOHMANN_JSON_PASTE(SIGHTMAP_OPTIONS_JSON_WRITE_FIELD,             \
                                             SIGHTMAP_OPTIONS_JSON_UNPAREN first))          \
    NLOHMANN_JSON_EXPAND(NLOHMANN_JSON_PASTE(SIGHTMAP_OPTIONS_JSON_WRITE_FIELD,             \
                                             SIGHTMAP_OPTIONS_JSON_UNPAREN second))         \
  }                                                                                         \
  void from_json(const nlohmann::json& json, Type& options) {                               \
    ::sightmap::options_json::CheckKeys(                                                    \
        json, SIGHTMAP_OPTIONS_JSON_STRING first ", " SIGHTMAP_OPTIONS_JSON_STRING second); \
    NLOHMANN_JSON_EXPAND(NLOHMANN_JSON_PASTE(SIGHTMAP_OPTIONS_JSON_READ_FIELD,              \
                                             SIGHTMAP_OPTIONS_JSON_UNPAREN first))          \
    NLOHMANN_JSON_EXPAND(NLOHMANN_JSON_PASTE(SIGHTMAP_OPTIONS_JSON_READ_FIELD,              \
                                             SIGHTMAP_OPTIONS_JSON_UNPAREN second))         \
  }
