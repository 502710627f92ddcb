#include "model/held_rest.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace pamc::model {

namespace {
constexpr int kLevels = 8;  // commands from u_lo to u_hi (and back down)
// Each held this long: a creep or a pressure's lag settles within it, and so does a payload's ringing that decays
// at zeta wn >= 0.84 /s (its swing, about 2 exp(-3 zeta wn) of a level's step, an eighth of the span, within the
// band over the hold's last second: at 2 Hz a damping ratio of 0.067 or more).
constexpr double kHoldSeconds = 4.0;
// ... but at most this many samples: a record sampled above 2 kHz holds for less (a check runs at every one of
// diagnose's validations).
constexpr int kHoldSamplesMax = 8000;
constexpr double kRestShare = 0.02;  // a swing within 2 % of the span is rest (a 2 % settling band)

// The commands of the staircase: up from u_lo to u_hi, then down to u_lo.
std::vector<double> levels(double u_lo, double u_hi) {
  std::vector<double> u;
  for (int i = 1; i <= kLevels; ++i) u.push_back(u_lo + (u_hi - u_lo) * i / kLevels);
  for (int i = kLevels - 1; i >= 0; --i) u.push_back(u_lo + (u_hi - u_lo) * i / kLevels);
  return u;
}

// The swing of y over the last quarter of one hold, and the output it ended at.
struct Hold {
  double swing = 0.0, end = 0.0;
  bool finite = true;
};
Hold hold(const Model& m, Model::State& st, const StepContext& c, double u, int samples) {
  Hold h;
  double lo = INFINITY, hi = -INFINITY;
  for (int i = 0; i < samples; ++i) {
    const double y = m.step(st, u, c);
    if (!std::isfinite(y)) h.finite = false;
    if (i >= samples - samples / 4) lo = std::min(lo, y), hi = std::max(hi, y);
    h.end = y;
  }
  h.swing = hi - lo;
  return h;
}
}  // namespace

HeldRest heldRest(const Model& m, double Ts, double u_lo, double u_hi, double span) {
  HeldRest r;
  r.Ts = Ts;
  if (!(Ts > 0.0) || !(u_hi > u_lo)) return r;
  StepContext c;
  c.Ts = Ts;
  Model::State st;
  m.init(st, u_lo, c);
  const int samples = std::clamp(static_cast<int>(std::ceil(kHoldSeconds / Ts)), 4, kHoldSamplesMax);
  std::vector<Hold> holds;
  const std::vector<double> u = levels(u_lo, u_hi);
  for (double v : u) holds.push_back(hold(m, st, c, v, samples));
  double end_lo = INFINITY, end_hi = -INFINITY;
  for (const Hold& h : holds) end_lo = std::min(end_lo, h.end), end_hi = std::max(end_hi, h.end);
  r.span = span > 0.0 ? span : m.range().known ? m.range().output.hi - m.range().output.lo : end_hi - end_lo;
  for (size_t i = 0; i < holds.size(); ++i) {
    const bool worse = !holds[i].finite || holds[i].swing > r.swing;
    if (worse) r.swing = holds[i].finite ? holds[i].swing : INFINITY, r.at_command = u[i];
  }
  r.rests = std::isfinite(r.swing) && std::isfinite(r.span) && r.swing <= kRestShare * std::max(r.span, 0.0);
  return r;
}

std::string describeHeldRest(const HeldRest& h) {
  char b[320];
  if (h.rests)
    std::snprintf(b, sizeof b,
                  "it comes to rest under a held command at %.4g ms (its largest swing %.3g over a hold's last "
                  "quarter, at most %g %% of its output's span %.4g)",
                  1e3 * h.Ts, h.swing, 100.0 * kRestShare, h.span);
  else
    std::snprintf(b, sizeof b,
                  "it does not come to rest under a held command at %.4g ms: under %.4g it swings over %.4g (its "
                  "output's span %.4g), so an inverse of it swings the valve",
                  1e3 * h.Ts, h.at_command, h.swing, h.span);
  return b;
}

}  // namespace pamc::model
