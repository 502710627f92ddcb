#include "app/controller_options.hpp"

#include <cstdio>

#include "io/model_file.hpp"

namespace pamc::app {

void ControllerOptions::add(CLI::App* a) {
  addGains(a);
  addStructure(a);
}

void ControllerOptions::addGains(CLI::App* a) {
  a->add_option("--kp", cc.kp, "PI proportional gain [V/mm]")->capture_default_str()->check(CLI::NonNegativeNumber);
  a->add_option("--ki", cc.ki,
                "PI integral gain [V/(mm s)] (the default: the calibrated reading of the paper's printed 0.15, "
                "docs/CALIBRATION.md)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  a->add_option("--kc", cc.kc, "AMC compensation gain [V/mm]")->capture_default_str()->check(CLI::NonNegativeNumber);
}

void ControllerOptions::addStructure(CLI::App* a) {
  a->add_option("--amc-form", amc_form,
                "eq. (17): 'printed' predicts Y_{k+1} from the nominal command itself (the paper); 'increment' adds "
                "the model's one-step increment to the posterior output; 'bus' predicts through the commands still "
                "on the bus first (a Smith predictor of eq. 17, at the horizon --delay + 1)")
      ->capture_default_str()
      ->check(CLI::IsMember({"printed", "increment", "bus"}));
  a->add_option("--amc-horizon", cc.amc_horizon,
                "AMC prediction horizon [samples]; 1 = eq. (17), 0 = automatic (bus delay + the model's response time)")
      ->capture_default_str()
      ->check(CLI::Range(0, 2000));
  a->add_option("--amc-inverse", cc.amc_inverse,
                "predictive AMC: fraction of the predicted error at the horizon corrected through the model's "
                "response (0: the paper's kc e_hat)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  a->add_option("--eso-form", eso_form,
                "the plant the ESO's observer assumes: 'printed' (the paper's eqs. 22-24: a double integrator with "
                "beta1..3, delta, b0) or 'first-order' (pamc's own: a lag, x1' = (gain u - x1)/tau + x2)")
      ->capture_default_str()
      ->check(CLI::IsMember({"first-order", "printed"}));
  a->add_option("--eso-gain", cc.eso.gain, "first-order ESO: static gain of its plant [mm/V]")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  a->add_option("--eso-tau", cc.eso.tau, "first-order ESO: time constant of its plant [s]")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  a->add_option("--eso-wo", cc.eso.wo, "first-order ESO: observer bandwidth [rad/s]")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  a->add_option("--eso-b0", cc.eso.b0, "printed ESO: input gain b0 [mm/(s^2 V)]")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  a->add_option("--eso-delta", cc.eso.delta, "printed ESO: fal() linear zone delta [mm]")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  a->add_option("--eso-beta1", cc.eso.beta1, "printed ESO: observer gain beta1")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  a->add_option("--eso-beta2", cc.eso.beta2, "printed ESO: observer gain beta2")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  a->add_option("--eso-beta3", cc.eso.beta3, "printed ESO: observer gain beta3")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  a->add_option("--delay", cc.delay_cycles,
                "cycles from command to the measurement that shows it, beyond one sample (2 on the CAN bus)")
      ->capture_default_str()
      ->check(CLI::Range(0, 7));
  a->add_option("--ukf-position-error", cc.ukf.Q_d,
                "MBC's UKF: random walk [mm^2 per sample] of the modelling error on the position that a model with "
                "output effects takes (0: the paper's error on h's rate, the lagging states in the filter; the AMC "
                "keeps the paper's)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  a->add_option(
       "--mbc-horizon", cc.mbc.horizon,
       "MBC: samples ahead its inverse reaches the setpoint at; 0 = automatic (bus delay + the model's response "
       "time)")
      ->capture_default_str()
      ->check(CLI::Range(0, 2000));
  a->add_option(
       "--mbc-error-tau", cc.mbc.error_tau_s,
       "MBC: time constant [s] of the filter on the UKF's modelling-error estimate the feedforward aims off by")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  a->add_option("--mbc-pace-share", cc.mbc.pace_share,
                "MBC: the setpoint governor's rate and acceleration lowered to this share of the model's own pace (its "
                "fastest speed and acceleration under a step across its input range) where that is below "
                "--mbc-rate and --mbc-accel; 0: those alone")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  a->add_option("--mbc-rate", cc.mbc.rate_mm_s,
                "MBC: the setpoint governor's rate [mm/s]: a setpoint step reaches the inverse and the PI at most this "
                "fast (a slower model's pace lowers it: --mbc-pace-share; 0: no governor)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  a->add_option("--mbc-accel", cc.mbc.accel_mm_s2,
                "MBC: the setpoint governor's acceleration [mm/s^2] (a slower model's pace lowers it)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  char carried[512];
  std::snprintf(carried, sizeof carried,
                "MBC: the setpoint governor's acceleration [mm/s^2] while the model carries the loop (its feedforward "
                "on and the PI's integral within %g %% of the command's span over the last %g s; a slower model's "
                "pace lowers it; at most --mbc-accel: off)",
                100.0 * cc.mbc.carried_share, cc.mbc.carried_tau_s);
  a->add_option("--mbc-accel-carried", cc.mbc.accel_carried_mm_s2, carried)
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  a->add_option("--model", model_file, "identified model (JSON) for the AMC's and MBC's UKF and the open loop");
}

control::ControllerConfig ControllerOptions::config() const {
  control::ControllerConfig c = cc;
  c.amc_as_printed = amc_form == "printed";
  c.amc_bus_aware = amc_form == "bus";
  c.eso.order = eso_form == "printed" ? 2 : 1;
  if (!model_file.empty()) c.model = io::readModelFile(model_file);
  return c;
}

control::ControllerConfig ControllerOptions::paperConfig() const {
  ControllerOptions o = *this;
  o.model_file.clear();  // the experiments read or identify their model themselves
  return o.config();
}

void ControllerKindOption::add(CLI::App* a) {
  a->add_option("--controller", name,
                "open, pi, pid (the same as pi: the paper's \"PID\" is a PI), eso, amc or mbc (model-based: the "
                "model's inverse through the commands in flight, the PI on top, the PI alone where the model was not "
                "identified or does not move as the muscle does; docs/CONTROL.md)")
      ->capture_default_str()
      ->check(CLI::IsMember({"open", "pi", "pid", "eso", "amc", "mbc"}));
}

}  // namespace pamc::app
