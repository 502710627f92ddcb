// The controller's settings by name - the one table of them: Python's keyword arguments
// (pamc.Controller(kind, kp=...)) and a sweep's record of what it ran with (robustness cells).
// The model and the UKF's settings are not among them.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "control/controller.hpp"

namespace pamc::io {

// Every named setting of `c`, as {"kp": 0.218, "mbc_horizon": 0, ...}.
nlohmann::json controllerSettingsToJson(const control::ControllerConfig& c);
// Sets the setting `name` to `value`; false when no setting has that name. Throws nlohmann's type_error
// for a value of the wrong type.
bool setControllerSetting(control::ControllerConfig& c, const std::string& name, const nlohmann::json& value);
// Sets every setting of `j`; throws std::invalid_argument naming an unknown one.
void applyControllerSettings(control::ControllerConfig& c, const nlohmann::json& j);

}  // namespace pamc::io
