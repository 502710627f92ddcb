#include "io/controller_settings.hpp"

#include <stdexcept>

namespace pamc::io {
namespace {

using control::ControllerConfig;

// Each setting by its name (the names of the Python module and the sweeps' settings records) and the
// field that holds it.
template <class T>
struct Setting {
  const char* name;
  T& (*ref)(ControllerConfig&);
};
#define PAMC_SETTING(T, name, field)                        \
  Setting<T> {                                              \
    name, [](ControllerConfig& c) -> T& { return c.field; } \
  }
constexpr Setting<double> kDoubles[] = {PAMC_SETTING(double, "Ts", Ts),
                                        PAMC_SETTING(double, "u_min", u_min),
                                        PAMC_SETTING(double, "u_max", u_max),
                                        PAMC_SETTING(double, "kp", kp),
                                        PAMC_SETTING(double, "ki", ki),
                                        PAMC_SETTING(double, "kc", kc),
                                        PAMC_SETTING(double, "amc_inverse", amc_inverse),
                                        PAMC_SETTING(double, "mbc_error_tau_s", mbc.error_tau_s),
                                        PAMC_SETTING(double, "mbc_rate_mm_s", mbc.rate_mm_s),
                                        PAMC_SETTING(double, "mbc_accel_mm_s2", mbc.accel_mm_s2),
                                        PAMC_SETTING(double, "mbc_accel_carried_mm_s2", mbc.accel_carried_mm_s2),
                                        PAMC_SETTING(double, "mbc_pace_share", mbc.pace_share),
                                        PAMC_SETTING(double, "beta1", eso.beta1),
                                        PAMC_SETTING(double, "beta2", eso.beta2),
                                        PAMC_SETTING(double, "beta3", eso.beta3),
                                        PAMC_SETTING(double, "delta", eso.delta),
                                        PAMC_SETTING(double, "b0", eso.b0),
                                        PAMC_SETTING(double, "eso_gain", eso.gain),
                                        PAMC_SETTING(double, "eso_tau", eso.tau),
                                        PAMC_SETTING(double, "eso_wo", eso.wo)};
constexpr Setting<int> kInts[] = {
    PAMC_SETTING(int, "amc_horizon", amc_horizon), PAMC_SETTING(int, "mbc_horizon", mbc.horizon),
    PAMC_SETTING(int, "eso_order", eso.order), PAMC_SETTING(int, "delay_cycles", delay_cycles)};
constexpr Setting<bool> kBools[] = {PAMC_SETTING(bool, "amc_as_printed", amc_as_printed),
                                    PAMC_SETTING(bool, "amc_bus_aware", amc_bus_aware),
                                    PAMC_SETTING(bool, "open_loop_linear", open_loop_linear)};
#undef PAMC_SETTING

template <class T, size_t N>
void addAll(nlohmann::json& j, const ControllerConfig& c, const Setting<T> (&table)[N]) {
  for (const auto& s : table) j[s.name] = s.ref(const_cast<ControllerConfig&>(c));  // read only
}

template <class T, size_t N>
bool setField(ControllerConfig& c, const Setting<T> (&table)[N], const std::string& name, const nlohmann::json& v) {
  for (const auto& s : table)
    if (name == s.name) {
      s.ref(c) = v.get<T>();
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
