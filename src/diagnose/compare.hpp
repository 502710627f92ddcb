// `pamc compare`: a model simulated on a measurement's input against the measured output.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "diagnose/residual.hpp"
#include "diagnose/spectrum.hpp"
#include "ident/identify.hpp"
#include "model/held_rest.hpp"
#include "model/inverse_fold.hpp"
#include "io/measurement.hpp"
#include "model/model.hpp"

namespace pamc::diagnose {

// The share of a record's samples outside the range the model was identified on (model::OperatingRange).
struct RangeShare {
  bool known = false;                                       // the model records its range
  double input = 0.0, output = 0.0, rate = 0.0, any = 0.0;  // fractions of the samples
};
RangeShare rangeShare(const model::OperatingRange& r, const io::Measurement& d);
// One line: "outside the range the model was identified on: 12.5 % of the samples (input 3.1 %, ...)".
std::string describeRangeShare(const RangeShare& s, const model::OperatingRange& r);

struct Comparison {
  std::vector<double> y_model;
  RangeShare outside;
  ident::RecordRests rests;  // whether the record rests on its end stops, as a fit reads it
  model::InverseFold fold;   // whether the model's inverse folds, over its input range (the record's without one)
  model::HeldRest rest;      // whether it comes to rest under a held command over that range, at the record's period
  ResidualReport report;
  ResidualSpectrum spectrum;  // of the residual, with its coherence with the input
};

Comparison compare(const model::Model& m, const io::Measurement& d);
nlohmann::json toJson(const Comparison& c);
// CSVs and figures (time plot, loops, residual, breakdown, residual tests) into dir.
void writeCompareReport(const Comparison& c, const io::Measurement& d, const std::string& dir,
                        std::vector<std::string>* warnings = nullptr);

}  // namespace pamc::diagnose
