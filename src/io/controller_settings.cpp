#include "io/controller_settings.hpp"

#include <stdexcept>

namespace pamc::io {
namespace {

using control::ControllerConfig;

template <class T>
struct Setting {
  const char* name;
  T ControllerConfig::*field;
};
constexpr Setting<double> kDoubles[] = {{"Ts", &ControllerConfig::Ts},
                                        {"u_min", &ControllerConfig::u_min},
                                        {"u_max", &ControllerConfig::u_max},
                                        {"kp", &ControllerConfig::kp},
                                        {"ki", &ControllerConfig::ki},
                                        {"kc", &ControllerConfig::kc},
                                        {"amc_inverse", &ControllerConfig::amc_inverse},
                                        {"mbc_error_tau_s", &ControllerConfig::mbc_error_tau_s},
                                        {"mbc_rate_mm_s", &ControllerConfig::mbc_rate_mm_s},
                                        {"mbc_accel_mm_s2", &ControllerConfig::mbc_accel_mm_s2},
                                        {"beta1", &ControllerConfig::beta1},
                                        {"beta2", &ControllerConfig::beta2},
                                        {"beta3", &ControllerConfig::beta3},
                                        {"delta", &ControllerConfig::delta},
                                        {"b0", &ControllerConfig::b0},
                                        {"eso_gain", &ControllerConfig::eso_gain},
                                        {"eso_tau", &ControllerConfig::eso_tau},
                                        {"eso_wo", &ControllerConfig::eso_wo}};
constexpr Setting<int> kInts[] = {{"amc_horizon", &ControllerConfig::amc_horizon},
                                  {"mbc_horizon", &ControllerConfig::mbc_horizon},
                                  {"eso_order", &ControllerConfig::eso_order},
                                  {"delay_cycles", &ControllerConfig::delay_cycles}};
constexpr Setting<bool> kBools[] = {{"amc_as_printed", &ControllerConfig::amc_as_printed},
                                    {"amc_bus_aware", &ControllerConfig::amc_bus_aware},
                                    {"open_loop_linear", &ControllerConfig::open_loop_linear}};

template <class T, size_t N>
void addAll(nlohmann::json& j, const ControllerConfig& c, const Setting<T> (&table)[N]) {
  for (const auto& s : table) j[s.name] = c.*s.field;
}

template <class T, size_t N>
bool setField(ControllerConfig& c, const Setting<T> (&table)[N], const std::string& name, const nlohmann::json& v) {
  for (const auto& s : table)
    if (name == s.name) {
      c.*s.field = v.get<T>();
      return true;
    }
  return false;
}

}  // namespace

nlohmann::json controllerSettingsToJson(const ControllerConfig& c) {
  nlohmann::json j = nlohmann::json::object();
  addAll(j, c, kDoubles);
  addAll(j, c, kInts);
  addAll(j, c, kBools);
  return j;
}

bool setControllerSetting(ControllerConfig& c, const std::string& name, const nlohmann::json& value) {
  return setField(c, kDoubles, name, value) || setField(c, kInts, name, value) || setField(c, kBools, name, value);
}

void applyControllerSettings(ControllerConfig& c, const nlohmann::json& j) {
  for (const auto& [name, value] : j.items())
    if (!setControllerSetting(c, name, value)) throw std::invalid_argument("unknown controller setting '" + name + "'");
}

}  // namespace pamc::io
