// The controller node's parameter objects (od/controller.eds) and their commit protocol.
//
//   0x2000 gains      kp ki kc beta1 beta2 beta3 delta b0 eso_gain eso_tau eso_wo, eso form (u8)     0x2010 controller
//   choice 0x2001 model      k rho b alpha beta gamma                0x2011/0x2012 trajectory 0x2002 UKF        P0_h
//   P0_f Q_h Q_f R Q_h_lag Q_f_lag Q_out diverge Q_d 0x2020 safe valve voltage   0x2021 missing-PDO limit   0x2022
//   plausibility (range, stuck time, span) 0x2003 commit: :01 = 1 commits the staged set, 0 discards it; :02 staged;
//   :03 sets applied
//
// The loop never reads these entries. A set is read from the dictionary, checked as an SDO write would
// be (plus the ranges only the application knows, and the model's stability as a whole), and adopted
// when the node enters Operational - or, while it runs, committed: checked and built in the SDO server,
// then taken by the cycle at its next boundary with pointer swaps only (take()).
#pragma once

#include <array>
#include <atomic>
#include <functional>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>

#include "nodes/process_data.hpp"
#include "canopen/node.hpp"
#include "control/controller.hpp"
#include "control/trajectory.hpp"
#include "nodes/controller_config.hpp"

namespace pamc::nodes {

struct ParameterSet {
  control::ControllerConfig ctrl;
  double safe_u = pd::kCommandMin;  // relative volts (0 V at the valve)
  unsigned missing_limit = 3;       // cycles without a position before the fault
  double range_steps = 100000;      // 0x2022:01 measuring range [steps of 0.001 mm]
  double stuck_s = 0.25;            // 0x2022:02
  double stuck_span_v = 1.0;        // 0x2022:03 (0: off)
};

// Trajectory choice 0x2011 and its parameters 0x2012 (throws on a choice outside 0..5).
control::Trajectory trajectoryFromOd(canopen::ObjectDictionary& od);
// False when the shape has no representation in 0x2011/0x2012.
bool trajectoryToOd(canopen::ObjectDictionary& od, const control::Trajectory& t);

class ControllerParameters {
 public:
  // base: what the dictionary does not hold (model effects, the AMC's form, ...). build_off_cycle: the
  // controller of a commit is built on a worker thread (on a rig: the open loop's inverse takes
  // milliseconds, several cycles of the thread that runs the node), not in the SDO server.
  ControllerParameters(canopen::Node& node, const control::ControllerConfig& base, bool build_off_cycle = false);
  ~ControllerParameters();
  ControllerParameters(const ControllerParameters&) = delete;
  ControllerParameters& operator=(const ControllerParameters&) = delete;

  // Dictionary <-> set. read() takes what the dictionary does not hold from the running set.
  ParameterSet read() const;
  void write(const ParameterSet& p);
  void writeGains(const control::ControllerConfig& c);
  void writeModel(const model::BoucWenParams& m);
  // The UKF's settings (0x2002), as the gains: a node started with them from its command line.
  void writeUkf(const estimation::ActiveModelSettings& u);
  // kSdoOk, or the abort code refusing the set; why names the entry or the condition.
  std::uint32_t check(const ParameterSet& p, std::string* why) const;

  // The SDO guards: objects of the cycle refused while Operational, finite numbers, the application's
  // ranges, staging of every write and the commit object 0x2003:01.
  void installGuards();

  // A node of several channels builds one controller per channel from a set (a channel may run its
  // own model or controller kind: the builder knows); one channel and makeController by default.
  using Builder = std::function<std::unique_ptr<control::Controller>(control::Kind, const control::ControllerConfig&,
                                                                     std::size_t channel)>;
  void setChannels(std::size_t n, Builder build);
  std::size_t channels() const noexcept { return n_; }

  // The set taken into use when the node enters Operational (built by the caller).
  void adopt(ParameterSet p, control::Kind kind);
  // 0x2003:01 = 1 (SDO server, between cycles): check, build a controller of the running kind (here or
  // on the worker), stage. Refused with kAbortDeviceState while the last commit is still being built.
  std::uint32_t commit();
  // 0x2003:01 = 0: the dictionary shows the running set again.
  void discard();
  // The cycle asks at its boundary: a committed set whose controller is built. Takes a finished
  // build from the worker (a pointer move; a failed build is counted as refused).
  bool committed() noexcept;
  // At a cycle boundary: the committed set and controllers become the running ones, ctrls[c] channel
  // c's (swaps only; the replaced controllers are freed at the next commit). Returns true if the safe
  // value changed.
  bool take(std::unique_ptr<control::Controller>* const* ctrls) noexcept;
  bool take(std::unique_ptr<control::Controller>& ctrl) noexcept {  // one channel
    std::unique_ptr<control::Controller>* one[] = {&ctrl};
    return take(one);
  }

  const ParameterSet& running() const noexcept { return running_; }
  double safeCommand() const noexcept { return safe_u_; }
  std::uint64_t applied() const noexcept { return applied_; }
  std::uint64_t refused() const noexcept { return refused_; }
  void countRefused() noexcept { ++refused_; }
  std::uint32_t lastRefusal() const noexcept { return last_refusal_; }

 private:
  void countApplied() noexcept;
  using Controllers = std::array<std::unique_ptr<control::Controller>, kMaxChannels>;
  bool buildAll(control::Kind kind, const control::ControllerConfig& ctrl, Controllers& into) const;

  canopen::Node& node_;
  canopen::Ref<std::uint8_t> staged_flag_{nullptr};
  canopen::Ref<std::uint8_t> sets_applied_{nullptr};
  ParameterSet running_, next_;
  control::Kind kind_ = control::Kind::PI;
  double safe_u_ = pd::kCommandMin;
  std::size_t n_ = 1;
  Builder build_;
  Controllers next_ctrl_;
  Controllers retired_;
  bool ready_ = false;
  // The worker's hand-over: it writes built_, then build_state_ (release); the cycle reads it (acquire).
  enum : int { kIdle, kBuilding, kBuilt, kFailed };
  bool off_cycle_ = false;
  std::thread worker_;
  std::atomic<int> build_state_{kIdle};
  Controllers built_;
  std::uint64_t applied_ = 0, refused_ = 0;
  std::uint32_t last_refusal_ = 0;
};

}  // namespace pamc::nodes
