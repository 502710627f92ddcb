// Model files (JSON): the reference model's parameters, its effects and how it was fitted.
//   {"format": "pamc-model/1", "core": {"k":..,"rho":..,"b":..,"alpha":..,"beta":..,"gamma":..},
//    "output_form": "aligned" | "printed" (model::OutputForm; a file without it is read as printed),
//    "effects": [{"name": "pressure_lag", "params": {"tau": 0.05, "slew": 1000}}, ...],
//    "range": {"input": [lo, hi], "output": [lo, hi], "input_rate": [lo, hi]} (where it was identified;
//              model::OperatingRange - absent in older files),
//    "fit": {...free-form provenance...}}
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "model/model.hpp"

namespace pamc::io {

nlohmann::json modelToJson(const model::Model& m);
// Throws InputError naming `where` and the bad key.
model::Model modelFromJson(const nlohmann::json& j, const std::string& where);
model::Model readModelFile(const std::string& path);
// A JSON file; throws InputError naming the path ("cannot open <what>", the byte of a syntax error).
nlohmann::json readJsonFile(const std::string& path, const std::string& what);
// Atomic write; `fit` is stored under "fit".
void writeModelFile(const std::string& path, const model::Model& m, const nlohmann::json& fit = {});

}  // namespace pamc::io
