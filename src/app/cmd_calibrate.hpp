#pragma once

#include <CLI/CLI.hpp>

#include <string>

namespace pamc::app {

class CalibrateCommand {
 public:
  explicit CalibrateCommand(CLI::App& app);
  bool selected() const { return cmd_->parsed(); }
  int run();

 private:
  CLI::App* cmd_ = nullptr;
  std::string lag_ = "0.04,0.1,0.15,0.2,0.25,0.3";
  std::string ki_ = "0.15,0.9,1.0,1.1,1.2,1.3";
  std::string forms_ = "printed,increment";
  std::string plant_, out_;
  std::string work_ = "calibration";
};

}  // namespace pamc::app
