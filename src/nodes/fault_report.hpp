// What the controller node's faults mean, in one line each, for whoever watches the node from outside
// the cycle (the `pamc controller` watcher thread, the in-process rig's harness), and how a run of the
// node ends: after its duration of trajectory, or by the clock whatever the slaves do.
#pragma once

#include <functional>
#include <optional>
#include <string>

#include "nodes/controller_node.hpp"

namespace pamc::nodes {

// One line for the node's present fault (None: the fault cleared), with what to look at.
std::string describeFault(const ControllerNode& n, Fault f);

// Prints a line whenever the node's fault changes, once when the model runs outside its range, and once when the MBC
// takes its feedforward off for a model that does not move as the muscle does. Reads only what the node publishes for
// other threads, so it may run on a thread of its own.
class FaultReporter {
 public:
  explicit FaultReporter(std::function<void(const std::string&)> out) : out_(std::move(out)) {}
  void step(const ControllerNode& n);

 private:
  std::function<void(const std::string&)> out_;
  Fault last_ = Fault::None;
  bool range_said_ = false;     // the model's range is said once a run
  bool distrust_said_ = false;  // so is the MBC's response monitor's verdict
};

// Why the run failed, for its end: it never had a position (the commands exit non-zero with it).
std::optional<std::string> runFailure(const ControllerNode& n);

// When a run ends: after duration_s of trajectory, and at the latest, on the run's own clock (wall
// clock on a bus, bus time in-process), kStartGraceS after pre-roll + duration from the start - a run
// whose sensor never sends ends on time too. duration_s <= 0: never.
class RunEnd {
 public:
  // What the slaves get for their boot and a first position before the clock ends the run (a rig file's
  // boot over SDO takes well under a second, also at the end-to-end test's 100 Hz in an emulated VM).
  static constexpr double kStartGraceS = 3.0;
  RunEnd(double duration_s, double preroll_s, canopen::TimeUs start_us)
      : duration_s_(duration_s),
        deadline_us_(start_us + static_cast<canopen::TimeUs>((preroll_s + duration_s + kStartGraceS) * 1e6)) {}
  bool reached(const ControllerNode& n, canopen::TimeUs now_us) const noexcept {
    return duration_s_ > 0 && (n.runTime() >= duration_s_ || now_us >= deadline_us_);
  }

 private:
  double duration_s_;
  canopen::TimeUs deadline_us_;
};

}  // namespace pamc::nodes
