#include "app/measurement_record.hpp"

#include <cmath>
#include <stdexcept>

#include "io/measurement.hpp"
#include "io/text.hpp"

namespace pamc::app {

void MeasurementRecord::add(const nodes::CycleRecord& r) {
  if (r.channel != 0) return;  // channel 1's (a measurement is one muscle's)
  if (!u_.empty() && r.k != k_last_ + 1) {
    if (gaps_ == 0) gap_at_ = r.t;
    ++gaps_;
  }
  if (u_.empty()) t_first_ = r.t;
  t_last_ = r.t;
  k_last_ = r.k;
  if (r.fault != 0) ++fault_cycles_;
  u_.push_back(r.u);
  y_.push_back(r.y);
  if (with_p_) p_.push_back(r.p);
}

// The cycle period from the records' own times (each is its cycle count times the period), to the microsecond.
double MeasurementRecord::period() const {
  const double Ts = (t_last_ - t_first_) / static_cast<double>(u_.size() - 1);
  return std::round(Ts * 1e6) * 1e-6;
}

void MeasurementRecord::write(const std::string& path) const {
  if (u_.size() < lag_ + 2)
    throw std::runtime_error(path + ": not written: " + std::to_string(u_.size()) +
                             " cycles recorded (the run never got going)");
  if (gaps_ > 0)
    throw std::runtime_error(path + ": not written: the cycle records have " + std::to_string(gaps_) + " gap" +
                             (gaps_ == 1 ? "" : "s") + ", the first at t = " + io::fmt("%.3f", gap_at_) +
                             " s (records lost or the loop started over): not an evenly sampled record");
  const double Ts = period();
  // Row i: the command of cycle i beside the position (and pressure) of cycle i + lag that reflects it.
  const std::size_t n = u_.size() - lag_;
  std::vector<double> t(n), u(u_.begin(), u_.begin() + static_cast<std::ptrdiff_t>(n));
  std::vector<double> y(y_.begin() + static_cast<std::ptrdiff_t>(lag_), y_.end());
  for (std::size_t i = 0; i < n; ++i) t[i] = static_cast<double>(i) * Ts;
  if (with_p_) {
    std::vector<double> p(p_.begin() + static_cast<std::ptrdiff_t>(lag_), p_.end());
    io::writeCsvAtomic(path, {"t", "u", "y", "p"}, {&t, &u, &y, &p});
  } else {
    io::writeCsvAtomic(path, {"t", "u", "y"}, {&t, &u, &y});
  }
}

}  // namespace pamc::app
