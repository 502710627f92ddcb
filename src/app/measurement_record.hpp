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

//
// The file is the plant's record, not the bus's: the position latched at cycle k was taken at cycle k-1
// and reflects the command computed at cycle k - (bus_delay_cycles + 1) (controller_node.hpp), so each
// y (and p, sampled with it) is written beside that command, and the first bus_delay_cycles + 1 cycles'
// positions, which no recorded command explains, are left out. A model identified on it holds the
// plant's lags only, as one identified on `pamc emulate`'s record does; the controllers add the bus's
// (--delay) themselves.
class MeasurementRecord {
 public:
  // with_pressure: a p column (the valve's pressure feedback).
  MeasurementRecord(bool with_pressure, int bus_delay_cycles)
      : with_p_(with_pressure), lag_(static_cast<std::size_t>(bus_delay_cycles) + 1) {}

  // One cycle: u the command that went to the valve, y the position the sensor gave, p the pressure.
  void add(const nodes::CycleRecord& r);
  std::size_t size() const noexcept { return u_.size() > lag_ ? u_.size() - lag_ : 0; }  // samples written
  std::uint64_t faultCycles() const noexcept { return fault_cycles_; }

  // Writes t,u,y[,p] atomically, t from 0 at the first record with the cycle period as its step. Throws
  // std::runtime_error (and writes nothing) with fewer than two records or a gap in the cycles (records
  // lost, or the loop started over): the file would not be an evenly sampled record.
  void write(const std::string& path) const;

 private:
  double period() const;

  bool with_p_;
  std::size_t lag_;  // cycles from a command to the position that reflects it
  std::vector<double> u_, y_, p_;
  double t_first_ = 0.0, t_last_ = 0.0;
  std::uint32_t k_last_ = 0;
  std::uint64_t gaps_ = 0, fault_cycles_ = 0;
  double gap_at_ = 0.0;  // trajectory time of the first gap
};

}  // namespace pamc::app
