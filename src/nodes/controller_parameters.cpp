#include "nodes/controller_parameters.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iterator>
#include <stdexcept>

#include "model/bouc_wen.hpp"
#include "nodes/process_data.hpp"

namespace pamc::nodes {

using canopen::Entry;
using canopen::NmtState;

namespace {

// The parameters in 0x2000 (gains), 0x2001 (model), 0x2002 (UKF) and 0x2022 (plausibility) by
// sub-index 1..n, read, written and checked alike.
// The gains: each a field of the controller's settings (some in its ESO's), and whether the
// application needs it above 0 (a divisor: ESO delta, b0, gain, tau and the bandwidth wo).
struct Gain {
  double& (*ref)(control::ControllerConfig&);
  bool divisor;
};
constexpr Gain kGains[] = {
    {[](control::ControllerConfig& c) -> double& { return c.kp; }, false},
    {[](control::ControllerConfig& c) -> double& { return c.ki; }, false},
    {[](control::ControllerConfig& c) -> double& { return c.kc; }, false},
    {[](control::ControllerConfig& c) -> double& { return c.eso.beta1; }, false},
    {[](control::ControllerConfig& c) -> double& { return c.eso.beta2; }, false},
    {[](control::ControllerConfig& c) -> double& { return c.eso.beta3; }, false},
    {[](control::ControllerConfig& c) -> double& { return c.eso.delta; }, true},
    {[](control::ControllerConfig& c) -> double& { return c.eso.b0; }, true},
    {[](control::ControllerConfig& c) -> double& { return c.eso.gain; }, true},
    {[](control::ControllerConfig& c) -> double& { return c.eso.tau; }, true},
    {[](control::ControllerConfig& c) -> double& { return c.eso.wo; }, true}};
double gainOf(const control::ControllerConfig& c, std::size_t i) {
  return kGains[i].ref(const_cast<control::ControllerConfig&>(c));  // read only
}
// 0x2000 sub 12, after the gains: the ESO's form (1 first-order, 2 as printed).
constexpr std::uint8_t kEsoFormSub = std::size(kGains) + 1;
constexpr double model::BoucWenParams::*kModel[] = {&model::BoucWenParams::k,    &model::BoucWenParams::rho,
                                                    &model::BoucWenParams::b,    &model::BoucWenParams::alpha,
                                                    &model::BoucWenParams::beta, &model::BoucWenParams::gamma};
constexpr double estimation::ActiveModelSettings::*kUkf[] = {
    &estimation::ActiveModelSettings::P0_h,    &estimation::ActiveModelSettings::P0_f,
    &estimation::ActiveModelSettings::Q_h,     &estimation::ActiveModelSettings::Q_f,
    &estimation::ActiveModelSettings::R,       &estimation::ActiveModelSettings::Q_h_lag,
    &estimation::ActiveModelSettings::Q_f_lag, &estimation::ActiveModelSettings::Q_out,
    &estimation::ActiveModelSettings::diverge, &estimation::ActiveModelSettings::Q_d};
constexpr double ParameterSet::*kPlausibility[] = {&ParameterSet::range_steps, &ParameterSet::stuck_s,
                                                   &ParameterSet::stuck_span_v};

constexpr std::uint8_t sub(std::size_t i) { return static_cast<std::uint8_t>(i + 1); }

// Ranges the application adds to the EDS limits: the gains that divide (kGains), and UKF R above 0.
constexpr bool isGainDivisor(std::uint8_t s) { return s >= 1 && s <= std::size(kGains) && kGains[s - 1].divisor; }
std::uint32_t applicationRange(std::uint16_t idx, std::uint8_t s, double v) {
  if (((idx == 0x2000 && isGainDivisor(s)) || (idx == 0x2002 && s == 5)) && !(v > 0.0))
    return canopen::kAbortValueTooLow;
  return canopen::kSdoOk;
}

}  // namespace

control::Trajectory trajectoryFromOd(canopen::ObjectDictionary& od) {
  const int choice = od.ref<std::uint8_t>(0x2011, 0).get();
  auto p = [&](std::uint8_t s) { return od.ref<double>(0x2012, s).get(); };
  switch (choice) {
    case 0: return control::Trajectory::constant(p(4));
    case 1: return control::Trajectory::triangle(p(1), p(2), p(3));
    case 2: return control::Trajectory::sine(p(1), p(5), p(4));
    case 3: return control::Trajectory::sineDescending(p(1), p(4), p(5), p(6), p(7));
    case 4: return control::Trajectory::square(p(1), p(2), p(3));
    case 5: return control::Trajectory::sawtooth(p(1), p(2), p(3));
  }
  throw std::invalid_argument("0x2011 trajectory choice " + std::to_string(choice) + " is not 0..5");
}

bool trajectoryToOd(canopen::ObjectDictionary& od, const control::Trajectory& t) {
  using S = control::Trajectory::Shape;
  int choice = 0;
  switch (t.shape) {
    case S::Constant: choice = 0; break;
    case S::Triangle: choice = 1; break;
    case S::Sine: choice = 2; break;
    case S::SineDescending:
      if (t.phase != 0.0) return false;  // the dictionary's descending sine starts at the trough
      choice = 3;
      break;
    case S::Square: choice = 4; break;
    case S::Sawtooth: choice = 5; break;
    default: return false;
  }
  od.ref<std::uint8_t>(0x2011, 0).set(static_cast<std::uint8_t>(choice));
  const double values[] = {t.freq_hz, t.lo, t.hi, t.offset, t.amplitude, t.amplitude_end, t.duration};
  for (std::size_t i = 0; i < std::size(values); ++i) od.ref<double>(0x2012, sub(i)).set(values[i]);
  return true;
}

ControllerParameters::ControllerParameters(canopen::Node& node, const control::ControllerConfig& base,
                                           bool build_off_cycle)
    : node_(node), off_cycle_(build_off_cycle) {
  running_.ctrl = base;
  // The command range is the valve's process-data range (process_data.hpp), whatever the base says.
  running_.ctrl.u_min = pd::kCommandMin;
  running_.ctrl.u_max = pd::kCommandMax;
  staged_flag_ = node_.od().ref<std::uint8_t>(0x2003, 2);
  sets_applied_ = node_.od().ref<std::uint8_t>(0x2003, 3);
}

ParameterSet ControllerParameters::read() const {
  auto& od = node_.od();
  ParameterSet p;
  p.ctrl = running_.ctrl;
  for (std::size_t i = 0; i < std::size(kGains); ++i) kGains[i].ref(p.ctrl) = od.ref<double>(0x2000, sub(i)).get();
  p.ctrl.eso.order = od.ref<std::uint8_t>(0x2000, kEsoFormSub).get();
  for (std::size_t i = 0; i < std::size(kModel); ++i)
    p.ctrl.model.core().*kModel[i] = od.ref<double>(0x2001, sub(i)).get();
  for (std::size_t i = 0; i < std::size(kUkf); ++i) p.ctrl.ukf.*kUkf[i] = od.ref<double>(0x2002, sub(i)).get();
  p.safe_u = pd::commandFromVolts(od.ref<double>(0x2020, 0).get());
  p.missing_limit = od.ref<std::uint8_t>(0x2021, 0).get();
  for (std::size_t i = 0; i < std::size(kPlausibility); ++i) p.*kPlausibility[i] = od.ref<double>(0x2022, sub(i)).get();
  return p;
}

void ControllerParameters::writeGains(const control::ControllerConfig& c) {
  for (std::size_t i = 0; i < std::size(kGains); ++i) node_.od().ref<double>(0x2000, sub(i)).set(gainOf(c, i));
  node_.od().ref<std::uint8_t>(0x2000, kEsoFormSub).set(static_cast<std::uint8_t>(c.eso.order));
}

void ControllerParameters::writeModel(const model::BoucWenParams& m) {
  for (std::size_t i = 0; i < std::size(kModel); ++i) node_.od().ref<double>(0x2001, sub(i)).set(m.*kModel[i]);
}

void ControllerParameters::writeUkf(const estimation::ActiveModelSettings& u) {
  for (std::size_t i = 0; i < std::size(kUkf); ++i) node_.od().ref<double>(0x2002, sub(i)).set(u.*kUkf[i]);
}

void ControllerParameters::write(const ParameterSet& p) {
  auto& od = node_.od();
  writeGains(p.ctrl);
  writeModel(p.ctrl.model.core());
  writeUkf(p.ctrl.ukf);
  od.ref<double>(0x2020, 0).set(pd::valveVolts(p.safe_u));
  od.ref<std::uint8_t>(0x2021, 0).set(static_cast<std::uint8_t>(p.missing_limit));
  for (std::size_t i = 0; i < std::size(kPlausibility); ++i) od.ref<double>(0x2022, sub(i)).set(p.*kPlausibility[i]);
}

std::uint32_t ControllerParameters::check(const ParameterSet& p, std::string* why) const {
  using canopen::kSdoOk;
  auto& od = node_.od();
  // Every value against the rules an SDO write would meet (values set locally skip those).
  auto value = [&](std::uint16_t idx, std::uint8_t s, double v) -> std::uint32_t {
    const Entry& e = od.entry(idx, s);
    std::uint32_t code = std::isfinite(v) ? kSdoOk : canopen::kAbortValueRange;
    if (code == kSdoOk) code = od.checkValue(e, reinterpret_cast<const std::uint8_t*>(&v), sizeof v);
    if (code == kSdoOk) code = applicationRange(idx, s, v);
    if (code != kSdoOk && why) {
      char b[160];
      std::snprintf(b, sizeof b, "%s %s = %g: %s", canopen::entryName(idx, s).c_str(), e.name().c_str(), v,
                    canopen::sdoAbortText(code));
      *why = b;
    }
    return code;
  };
  for (std::size_t i = 0; i < std::size(kGains); ++i)
    if (auto c = value(0x2000, sub(i), gainOf(p.ctrl, i))) return c;
  for (std::size_t i = 0; i < std::size(kModel); ++i)
    if (auto c = value(0x2001, sub(i), p.ctrl.model.core().*kModel[i])) return c;
  for (std::size_t i = 0; i < std::size(kUkf); ++i)
    if (auto c = value(0x2002, sub(i), p.ctrl.ukf.*kUkf[i])) return c;
  if (auto c = value(0x2020, 0, pd::valveVolts(p.safe_u))) return c;
  for (std::size_t i = 0; i < std::size(kPlausibility); ++i)
    if (auto c = value(0x2022, sub(i), p.*kPlausibility[i])) return c;
  // Each value may be fine alone and the set still unusable: CiA 301 "general parameter incompatibility".
  if (!model::boucWenStable(p.ctrl.model.core(), pd::kCommandMin, pd::kCommandMax, why))
    return canopen::kAbortParameterIncompatible;
  return kSdoOk;
}

void ControllerParameters::installGuards() {
  using canopen::kAbortDeviceState;
  using canopen::kAbortValueRange;
  using canopen::kSdoOk;
  auto& od = node_.od();
  // What the loop is wired to cannot change under it: the controller choice, the trajectory, the
  // process data, and the communication objects of the cycle are refused while Operational.
  auto while_running = [this](const Entry&, const std::uint8_t*, std::size_t) -> std::uint32_t {
    return node_.nmtState() == NmtState::Operational ? kAbortDeviceState : kSdoOk;
  };
  for (std::uint16_t idx : {0x1005, 0x1006, 0x1007, 0x1016, 0x1400, 0x1401, 0x1600, 0x1601, 0x1800, 0x1A00, 0x2010,
                            0x2011, 0x2012, 0x3000, 0x3001, 0x3002}) {
    if (od.hasObject(idx)) od.addValidator(idx, while_running);
  }
  // Numbers: finite (the EDS limits are checked before the validators run).
  auto finite = [](const Entry& e, const std::uint8_t* d, std::size_t len) -> std::uint32_t {
    if (e.dataType() != canopen::DataType::Real64 || len != 8) return kSdoOk;
    double v;
    std::memcpy(&v, d, 8);
    return std::isfinite(v) ? kSdoOk : kAbortValueRange;
  };
  for (std::uint16_t idx : {0x2000, 0x2001, 0x2002, 0x2012, 0x2020, 0x2022}) od.addValidator(idx, finite);
  for (std::uint8_t s = 1; s <= std::size(kGains); ++s)
    od.validate<double>(0x2000, s, [s](double v) { return applicationRange(0x2000, s, v); });
  od.validate<double>(0x2002, 5, [](double v) { return applicationRange(0x2002, 5, v); });
  // A parameter written while the loop runs is staged: the dictionary shows it, the loop does not use it.
  auto staged = [this](Entry&) { staged_flag_.set(1); };
  for (std::uint16_t idx : {0x2000, 0x2001, 0x2002, 0x2020, 0x2021, 0x2022}) od.addObserver(idx, staged);
  od.addValidator(0x2003, 1, [this](const Entry&, const std::uint8_t* d, std::size_t len) -> std::uint32_t {
    if (len != 1) return kSdoOk;
    if (d[0] == 1) return commit();
    discard();
    return kSdoOk;
  });
  od.addObserver(0x2003, 1, [](Entry& e) { e.set<std::uint8_t>(0); });
}

void ControllerParameters::setChannels(std::size_t n, Builder build) {
  if (n < 1 || n > kMaxChannels) throw std::invalid_argument("controller: " + std::to_string(n) + " channels (1..8)");
  n_ = n;
  build_ = std::move(build);
}

// Every channel's controller of a set; false (nothing kept) when one does not build.
bool ControllerParameters::buildAll(control::Kind kind, const control::ControllerConfig& ctrl,
                                    Controllers& into) const {
  try {
    for (std::size_t c = 0; c < n_; ++c) into[c] = build_ ? build_(kind, ctrl, c) : control::makeController(kind, ctrl);
    return true;
  } catch (const std::exception&) {
    for (auto& p : into) p.reset();
    return false;
  }
}

void ControllerParameters::countApplied() noexcept {
  ++applied_;
  sets_applied_.set(static_cast<std::uint8_t>(applied_));
}

void ControllerParameters::adopt(ParameterSet p, control::Kind kind) {
  // A commit still being built belongs to the set this one replaces.
  if (worker_.joinable()) worker_.join();
  for (auto& b : built_) b.reset();
  build_state_.store(kIdle, std::memory_order_relaxed);
  running_ = std::move(p);
  kind_ = kind;
  safe_u_ = std::clamp(running_.safe_u, pd::kCommandMin, pd::kCommandMax);
  for (auto& c : next_ctrl_) c.reset();
  ready_ = false;
  staged_flag_.set(0);
  countApplied();
}

ControllerParameters::~ControllerParameters() {
  if (worker_.joinable()) worker_.join();
}

bool ControllerParameters::committed() noexcept {
  if (ready_) return true;
  const int st = build_state_.load(std::memory_order_acquire);
  if (st == kBuilt) {
    std::swap(next_ctrl_, built_);  // the previous next_ctrl_ is empty: nothing freed here
    build_state_.store(kIdle, std::memory_order_relaxed);
    ready_ = true;
  } else if (st == kFailed) {
    ++refused_;
    last_refusal_ = canopen::kAbortParameterIncompatible;
    build_state_.store(kIdle, std::memory_order_relaxed);
  }
  return ready_;
}

std::uint32_t ControllerParameters::commit() {
  if (build_state_.load(std::memory_order_acquire) == kBuilding) return canopen::kAbortDeviceState;
  if (worker_.joinable()) worker_.join();  // finished: its result was taken or is waiting
  ParameterSet p = read();
  std::string why;
  std::uint32_t code = check(p, &why);
  if (code == canopen::kSdoOk && off_cycle_) {
    // The checks that make a build fail are the ones above and validate(); the worker only builds.
    try {
      control::validate(p.ctrl);
    } catch (const std::exception&) {
      code = canopen::kAbortParameterIncompatible;
    }
    if (code == canopen::kSdoOk) {
      for (auto& r : retired_) r.reset();
      next_ = p;
      ready_ = false;
      staged_flag_.set(0);
      build_state_.store(kBuilding, std::memory_order_relaxed);
      worker_ = std::thread([this, kind = kind_, ctrl = std::move(p.ctrl)] {
        build_state_.store(buildAll(kind, ctrl, built_) ? kBuilt : kFailed, std::memory_order_release);
      });
      return canopen::kSdoOk;
    }
  }
  Controllers c;
  if (code == canopen::kSdoOk && !buildAll(kind_, p.ctrl, c)) code = canopen::kAbortParameterIncompatible;
  if (code != canopen::kSdoOk) {
    ++refused_;
    last_refusal_ = code;
    return code;
  }
  for (auto& r : retired_) r.reset();  // the controllers replaced at the last cycle boundary
  std::swap(next_ctrl_, c);
  next_ = std::move(p);
  ready_ = true;
  staged_flag_.set(0);
  return canopen::kSdoOk;
}

void ControllerParameters::discard() {
  write(running_);
  staged_flag_.set(0);
}

bool ControllerParameters::take(std::unique_ptr<control::Controller>* const* ctrls) noexcept {
  for (std::size_t c = 0; c < n_; ++c) {
    std::swap(*ctrls[c], next_ctrl_[c]);
    retired_[c].swap(next_ctrl_[c]);
  }
  std::swap(running_, next_);
  ready_ = false;
  safe_u_ = std::clamp(running_.safe_u, pd::kCommandMin, pd::kCommandMax);
  countApplied();
  return running_.safe_u != next_.safe_u;
}

}  // namespace pamc::nodes
