// A passive live view of a CANopen bus decoded through the EDS files: node states from their
// heartbeats, SYNC rate and jitter, bus load, the latest PDO values in engineering units, EMCYs.
#pragma once

#include <deque>
#include <map>
#include <string>

#include "nodes/decoder.hpp"

namespace pamc::nodes {

class Monitor {
 public:
  explicit Monitor(BusDictionary dict, double bitrate = 1e6) : dict_(std::move(dict)), bitrate_(bitrate) {}
  void feed(const canopen::Frame& f, double t_s);
  // The screen at time t_s (statistics over the last window_s).
  std::string render(double t_s, double window_s = 1.0) const;
  std::uint64_t emcys() const { return emcy_count_; }

 private:
  BusDictionary dict_;
  double bitrate_;
  struct NodeInfo {
    int state = -1;
    double last_hb = -1;
  };
  std::map<std::uint8_t, NodeInfo> nodes_;
  std::deque<std::pair<double, double>> frames_;  // (time, bits) in the window
  std::deque<double> syncs_;
  std::map<std::string, std::pair<double, std::string>> values_;  // column -> value, unit
  std::deque<std::string> emcy_log_;
  std::uint64_t emcy_count_ = 0, total_ = 0, unknown_ = 0, bad_length_ = 0;
};

}  // namespace pamc::nodes
