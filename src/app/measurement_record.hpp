// The measurement of an open-loop run on the bus (`--input ... --out FILE` of `pamc controller` and
// `pamc rig run`): the cycle records turned into the measurement CSV that fit, compare and diagnose read
// (t,u,y and p where the rig maps a pressure). Fed by the thread that drains the records (the logger's,
// or the virtual rig's sink), never by the cycle: it allocates.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "nodes/cycle_stats.hpp"

namespace pamc::app {

class MeasurementRecord {
 public:
  // with_pressure: a p column (the valve's pressure feedback).
  explicit MeasurementRecord(bool with_pressure) : with_p_(with_pressure) {}

  // One cycle: u the command that went to the valve, y the position the sensor gave, p the pressure.
  void add(const nodes::CycleRecord& r);
  std::size_t size() const noexcept { return u_.size(); }
  std::uint64_t faultCycles() const noexcept { return fault_cycles_; }

  // Writes t,u,y[,p] atomically, t from 0 at the first record with the cycle period as its step. Throws
  // std::runtime_error (and writes nothing) with fewer than two records or a gap in the cycles (records
  // lost, or the loop started over): the file would not be an evenly sampled record.
  void write(const std::string& path) const;

 private:
  double period() const;

  bool with_p_;
  std::vector<double> u_, y_, p_;
  double t_first_ = 0.0, t_last_ = 0.0;
  std::uint32_t k_last_ = 0;
  std::uint64_t gaps_ = 0, fault_cycles_ = 0;
  double gap_at_ = 0.0;  // trajectory time of the first gap
};

}  // namespace pamc::app
