// fuzz_model_json: model file text through readModelFile (JSON parse + modelFromJson), then what
// every user of a model does: simulate it (init and 200 steps of a 0..10 V ramp at 1 kHz), and write
// it back (modelToJson) and read that again.
// Documented error: io::InputError, one line starting with the file name. Anything else - another
// exception, a crash, a sanitizer report in the reader or in the model it accepted - is a finding.
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "fuzz_util.hpp"
#include "io/measurement.hpp"
#include "io/model_file.hpp"

using pamc::fuzz::finding;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static pamc::fuzz::InputFile file;
  const std::string& path = file.write(data, size);
  pamc::model::Model m;
  try {
    m = pamc::io::readModelFile(path);
  } catch (const pamc::io::InputError& e) {
    pamc::fuzz::checkMessage(e.what(), path);
    return 0;
  }
  std::vector<double> u(200);
  for (std::size_t i = 0; i < u.size(); ++i) u[i] = 10.0 * static_cast<double>(i % 100) / 99.0;
  std::vector<double> load(u.size(), 50.0);
  const std::vector<double> y = m.simulate(u, 1e-3, load);
  if (y.size() != u.size()) finding("simulate returned the wrong length");

  const pamc::model::Model back = pamc::io::modelFromJson(pamc::io::modelToJson(m), "round trip");
  if (back.effectNames() != m.effectNames()) finding("effects change on a write/read round trip");
  const std::vector<double> p = m.params(), q = back.params();
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (!(p[i] == q[i])) finding("parameter " + std::to_string(i) + " changes on a write/read round trip");
  }
  return 0;
}
