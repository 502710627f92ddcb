// `pamc compare`: a model simulated on a measurement's input against the measured output.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "diagnose/residual.hpp"
#include "diagnose/spectrum.hpp"
#include "io/measurement.hpp"
#include "model/model.hpp"

namespace pamc::diagnose {

struct Comparison {
  std::vector<double> y_model;
  ResidualReport report;
  ResidualSpectrum spectrum;  // of the residual, with its coherence with the input
};

Comparison compare(const model::Model& m, const io::Measurement& d);
nlohmann::json toJson(const Comparison& c);
// CSVs and figures (time plot, loops, residual, breakdown, residual tests) into dir.
void writeCompareReport(const Comparison& c, const io::Measurement& d, const std::string& dir, std::vector<std::string>* warnings = nullptr);

}  // namespace pamc::diagnose
