#include "app/command.hpp"

#include <cstdio>

#include "diagnose/compare.hpp"
#include "io/measurement.hpp"
#include "io/model_file.hpp"

namespace pamc::app {
namespace {

// pamc compare: where a model fails on a measurement (docs/MODELING.md).
class CompareCommand final : public Command {
 public:
  explicit CompareCommand(CLI::App& app)
      : Command(app.add_subcommand("compare",
                                   "simulate a model on a measurement's input and show where it fails: "
                                   "RMSE, max error, fit %, error by where it happens, residual tests, figures")) {
    cmd_->add_option("model", cmp_model, "model file (JSON, from `pamc fit` or `pamc diagnose`)")->required();
    cmd_->add_option("data", cmp_data, "measurement CSV with header t,u,y")->required();
    cmd_->add_option("--out-dir", cmp_report, "folder for CSVs and figures (default: DATA.compare/)");
    addOldSpelling(cmd_, "--report", "--out-dir", cmp_report);
    cmd_->add_option("--json", cmp_json, "write the numbers as JSON to this file");
  }
  int run() override {
    const auto m = io::readModelFile(cmp_model);
    std::vector<std::string> warnings;
    const auto d = io::readMeasurementCsv(cmp_data, &warnings);
    printWarnings(warnings);
    const auto c = diagnose::compare(m, d);
    std::printf("model %s (%s) on %s: %zu samples, Ts = %g s\n", cmp_model.c_str(), m.describe().c_str(),
                cmp_data.c_str(), d.size(), d.Ts);
    std::printf("%s", diagnose::formatReport(c.report).c_str());
    std::printf("%s.\n", diagnose::describeRangeShare(c.outside, m.range()).c_str());
    std::printf("The record's %s.\n", ident::describeRests(c.rests).c_str());
    std::printf("The model: %s.\n", model::describeInverseFold(c.fold).c_str());
    std::printf("The model: %s.\n", model::describeHeldRest(c.rest).c_str());
    std::printf("The residual in frequency: %s.\n", diagnose::describeSpectrum(c.spectrum).c_str());
    std::string dir = cmp_report.empty() ? cmp_data + ".compare" : cmp_report;
    diagnose::writeCompareReport(c, d, dir, &warnings);
    printWarnings(warnings);
    std::printf("figures and CSVs in %s/\n", dir.c_str());
    if (!cmp_json.empty()) io::writeFileAtomic(cmp_json, diagnose::toJson(c).dump(2) + "\n");
    return 0;
  }

 private:
  std::string cmp_model, cmp_data, cmp_report, cmp_json;
};

}  // namespace

std::unique_ptr<Command> makeCompareCommand(CLI::App& app) { return std::make_unique<CompareCommand>(app); }

}  // namespace pamc::app
