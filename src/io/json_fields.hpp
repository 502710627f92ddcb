// Checked reading of a JSON configuration's fields: every failure is one std::invalid_argument that names
// the place ("where": the file and section) and the key. Header-only and free of the model, so that the
// physics plant, which shares no code with src/model, reads its files the same way as the model plant.
#pragma once

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace pamc::io::json_fields {

[[noreturn]] inline void fail(const std::string& where, const std::string& what) {
  throw std::invalid_argument(where + ": " + what);
}

inline double number(const nlohmann::json& j, const std::string& key, const std::string& where) {
  if (!j.is_number()) fail(where, "'" + key + "' must be a number");
  const double v = j.get<double>();
  if (!std::isfinite(v)) fail(where, "'" + key + "' must be finite");
  return v;
}

inline bool flag(const nlohmann::json& j, const std::string& key, const std::string& where) {
  if (!j.is_boolean()) fail(where, "'" + key + "' must be true or false");
  return j.get<bool>();
}

// A count of things: an integer from 1 to 100000.
inline int count(const nlohmann::json& j, const std::string& key, const std::string& where) {
  if (!j.is_number_integer()) fail(where, "'" + key + "' must be an integer");
  const auto v = j.get<long long>();
  if (v < 1 || v > 100000) fail(where, "'" + key + "' must be between 1 and 100000");
  return static_cast<int>(v);
}

inline std::string list(const std::vector<std::string>& keys) {
  std::string s;
  for (const auto& k : keys) s += (s.empty() ? "" : ", ") + k;
  return s;
}

// `j` is an object with no keys but `keys` (each optional).
inline void onlyKeys(const nlohmann::json& j, const std::vector<std::string>& keys, const std::string& where) {
  if (!j.is_object()) fail(where, "expected an object");
  for (auto it = j.begin(); it != j.end(); ++it)
    if (std::find(keys.begin(), keys.end(), it.key()) == keys.end())
      fail(where, "unknown key '" + it.key() + "' (known: " + list(keys) + ")");
}

}  // namespace pamc::io::json_fields
