#include "app/command.hpp"

#include <fcntl.h>
#include <time.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

#include "app/bus_common.hpp"
#include "app/controller_options.hpp"
#include "app/node_options.hpp"
#include "io/measurement.hpp"
#include "nodes/decoder.hpp"
#include "nodes/monitor.hpp"
#include "rig/fault_rig.hpp"
#include "rig/virtual_rig.hpp"

namespace pamc::app {
namespace {

// pamc decode: a candump log into a measurement CSV through the EDS files' PDO mappings.
class DecodeCommand final : public Command {
 public:
  explicit DecodeCommand(CLI::App& app)
      : Command(app.add_subcommand("decode",
                                   "turn a candump log into a measurement CSV (t,u,y,p,...) through the PDO "
                                   "mappings of the EDS files")) {
    cmd_->add_option("log", log_in, "candump -l log (from candump or the nodes)")->required();
    od_.add(cmd_);
    dict_.add(cmd_);
    cmd_->add_option("--out", out, "measurement CSV to write (default: LOG.csv)");
  }
  int run() override {
    const auto dict = dict_.load(od_);
    std::vector<std::string> warnings;
    const auto log = canopen::readCandumpLog(log_in, &warnings);
    printWarnings(warnings);
    const auto run = nodes::decodeCandump(log, dict);
    if (run.rows.size() < 3)
      throw std::runtime_error(log_in + ": no complete cycles (SYNC, position and valve command) found in the log");
    std::string text;
    for (size_t i = 0; i < run.columns.size(); ++i) text += (i ? "," : "") + run.columns[i];
    text += '\n';
    char b[64];
    for (const auto& r : run.rows) {
      for (size_t i = 0; i < r.size(); ++i) {
        if (std::isnan(r[i]))
          std::snprintf(b, sizeof b, "%s", i ? "," : "");
        else
          std::snprintf(b, sizeof b, "%s%.9g", i ? "," : "", r[i]);
        text += b;
      }
      text += '\n';
    }
    const std::string dst = out.empty() ? log_in + ".csv" : out;
    io::writeFileAtomic(dst, text);
    if (run.held)
      std::fprintf(stderr, "warning: %llu cycles had no position PDO; their position holds the last value\n",
                   static_cast<unsigned long long>(run.held));
    std::printf(
        "%s: %llu frames, %llu SYNCs -> %zu rows (%zu columns) in %s; %llu frames of unknown COB-ID, %llu of "
        "wrong length\n",
        log_in.c_str(), static_cast<unsigned long long>(run.frames), static_cast<unsigned long long>(run.syncs),
        run.rows.size(), run.columns.size(), dst.c_str(), static_cast<unsigned long long>(run.unknown),
        static_cast<unsigned long long>(run.bad_length));
    return 0;
  }

 private:
  std::string log_in, out;
  OdOption od_;
  BusDictionaryOptions dict_;
};

}  // namespace

std::unique_ptr<Command> makeDecodeCommand(CLI::App& app) { return std::make_unique<DecodeCommand>(app); }

}  // namespace pamc::app
