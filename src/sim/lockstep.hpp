// Lockstep simulation in virtual time: plant emulator and controller advance together, one
// 1 kHz cycle at a time, with the cycle order of the CANopen node:
//   SYNC -> latch position y_k -> estimate -> control -> send u_k
// and the valve applying u_k from the next SYNC on, the position reaching the controller one SYNC
// after it was sampled (delay_cycles = 2 on the bus): the plant holds u_{k-2} during (k, k+1].
#pragma once

#include <array>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "control/controller.hpp"
#include "plant/plant.hpp"
#include "control/trajectory.hpp"

namespace pamc::sim {

using control::Trajectory;

struct Record {
  std::vector<double> t, yd, y, y_true, u, u_n, u_c, y_hat, force, p;
  void reserve(size_t n);
  // Writes t,yd,y,y_true,u,u_n,u_c,y_hat,force,p atomically.
  void writeCsv(const std::string& path) const;
};

struct ClosedLoopRun {
  Trajectory reference;
  double duration_s = 40.0;
  double force_step_time_s = -1.0;  // < 0: no payload step
  double force_N = 0.0;
  int delay_cycles = control::kBusDelayCycles;
  // Before t = 0 the loop holds the first setpoint this long, as one homes a rig before a run;
  // not recorded.
  double preroll_s = 5.0;
  // The position held in the pre-roll; NaN: the first setpoint. Elsewhere, the run starts with a jump
  // from there to the first setpoint, as when a trajectory is started on a muscle parked at home.
  double home_mm = NAN;
  double home() const { return std::isnan(home_mm) ? reference.at(0.0) : home_mm; }
  bool startsAwayFromHome() const { return !std::isnan(home_mm); }
};

// The closed loop declared once and then stepped. The constructor takes the controller, the plant
// and the run; start() puts the plant at rest under u0, activates the controller and holds the first
// setpoint for the pre-roll; each step() is one cycle (latch -> estimate -> control -> send -> the
// plant advances one sample) and appends a row to the record. Hooks inject faults without copying
// the loop: what the controller is given as the position, and what the valve applies.
class Lockstep {
 public:
  struct Hooks {
    std::function<double(long k, double y_read)> measurement;  // the position handed to the controller
    std::function<double(long k, double u_applied)> valve;     // the command the valve applies
  };
  Lockstep(control::Controller& ctrl, plant::Plant& plant, const ClosedLoopRun& run, double u0, Hooks hooks = {});

  void start();
  const control::ControlOutput& step();
  bool done() const { return k_ >= n_; }
  long cycle() const { return k_; }                    // cycles stepped since start()
  double lastMeasurement() const { return y_given_; }  // what the controller was given in the last step
  double lastApplied() const { return pipe_[static_cast<size_t>(d_)]; }  // the command the valve holds
  const Record& record() const { return rec_; }
  Record& record() { return rec_; }

 private:
  double send(double u);

  control::Controller& ctrl_;
  plant::Plant& plant_;
  ClosedLoopRun run_;
  double u0_;
  Hooks hooks_;
  double Ts_;
  long n_, k_ = 0;
  int d_;
  std::array<double, 8> pipe_{};  // commands in flight to the valve (index 0 = sent this cycle)
  control::ControlOutput out_;
  double y_given_ = 0.0;
  Record rec_;
};

// Runs `ctrl` on `plant` from rest at the reference's start. u0 starts the plant and the
// controller (e.g. the open-loop inverse of the first setpoint).
Record runClosedLoop(control::Controller& ctrl, plant::Plant& plant, const ClosedLoopRun& run, double u0);

// Open loop: command u(t) straight to the valve; row k holds u_k and the position measured at
// the end of the sample it was held for.
Record runOpenLoopInput(plant::Plant& plant, const Trajectory& u, double duration_s,
                        const Trajectory* force_N = nullptr);
// The same for a command given sample by sample (a recorded input replayed); force_N may be null.
Record runOpenLoopSamples(plant::Plant& plant, const std::vector<double>& u,
                          const std::vector<double>* force_N = nullptr);

struct TrackingStats {
  double rmse = 0, max_abs = 0;
};
TrackingStats tracking(const Record& r, double from_s = 0.0);
// The time at which the measured position first reaches the reference (the error changes sign or
// vanishes); the record's end if it never does. Tracking scored from here leaves out the rise from
// home to a trajectory that starts elsewhere, and keeps the overshoot and the oscillation after it.
double firstReach(const Record& r);
// Where a run's tracking is scored from: its first reach when it starts away from home (the rise is not
// tracking), else 0.
double scoredFrom(const Record& r, const ClosedLoopRun& run);
// The largest |error| within window_s after each turning point of the reference (where its slope
// changes sign: a triangle's corners); 0 when the reference has none.
double turningPointError(const Record& r, double window_s);
// RMSE of the error over [t0, t1) (a hold: the steady state's noise and limit cycle).
double windowRmse(const Record& r, double t0, double t1);

struct StepStats {
  double overshoot_pct = 0;  // mean over the steps
  double settling_s = 0;     // mean time to stay within the band
  int steps = 0;
  int unsettled = 0;  // steps still outside the band when the next one came
  // Ringing, the worst step: how often the error changes side of the target (counted when it leaves a
  // band of 1 % of the jump on the other side; an overshoot that comes back is 2), and how often the
  // valve command, seen through a 20 Hz low-pass, reverses its direction by more than 0.05 V (a clean
  // step: kick, then settle = 1-2).
  int max_error_crossings = 0;
  int max_u_reversals = 0;
};
// Steps of the reference by at least min_jump; direction +1 rising, -1 falling; band as a
// fraction of the jump (0.02 = 2 %).
StepStats stepResponse(const Record& r, int direction, double min_jump, double band_frac);

struct RecoveryStats {
  double peak_dev_mm = 0;
  double recovery_s = 0;  // until |e| stays below the band
  bool recovered = true;  // false: still outside the band at the end of the record
};
RecoveryStats recovery(const Record& r, double t_event, double band_mm);

}  // namespace pamc::sim
