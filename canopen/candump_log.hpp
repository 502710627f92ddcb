// candump -l log lines: "(1700000000.123456) vcan0 181#0102030405060708" (can-utils format).
#pragma once

#include <cstdint>
#include <iosfwd>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "canopen/bus.hpp"
#include "canopen/frame.hpp"

namespace pamc::canopen {

struct CandumpRecord {
  TimeUs unix_time_us = 0;
  std::string interface;
  Frame frame;
};

// "123#R", "123#R4" (remote with DLC), "12345678#..." (29-bit), "20000004#..." (error frame: CAN_ERR_FLAG id).
std::string formatFrame(const Frame& f);
// One log line without newline: six decimals, uppercase hex.
std::string formatCandumpLine(const Frame& f, TimeUs unix_time_us, std::string_view interface);
// Parses a frame token like "181#0102" (also "181#01.02", "1FFFFFFF#R", "123#R8"); false with a reason if bad.
bool parseFrame(std::string_view token, Frame& out, std::string* error = nullptr);
// Parses a log line; trailing tokens after the frame (e.g. direction flags) are ignored.
bool parseCandumpLine(std::string_view line, CandumpRecord& out, std::string* error = nullptr);

// Reads a whole log; empty lines are skipped. Throws std::runtime_error "name:line: problem".
// A last line without its newline is a record cut off by a crash of the writer: it is ignored, and
// appended to *warnings (if given, one line each): "name:line: truncated last line ignored ...".
std::vector<CandumpRecord> readCandumpLog(std::istream& in, const std::string& name,
                                          std::vector<std::string>* warnings = nullptr);
std::vector<CandumpRecord> readCandumpLog(const std::string& path, std::vector<std::string>* warnings = nullptr);

class CandumpWriter {
 public:
  // Opens (truncates) path; throws std::runtime_error if it cannot.
  CandumpWriter(const std::string& path, std::string interface);
  // Writes to a stream the caller keeps alive.
  CandumpWriter(std::ostream& out, std::string interface);
  ~CandumpWriter();
  CandumpWriter(const CandumpWriter&) = delete;
  CandumpWriter& operator=(const CandumpWriter&) = delete;

  void write(const Frame& f, TimeUs unix_time_us);
  void flush();
  // Tap for a VirtualBus: bus time t is logged as epoch_us + t.
  VirtualBus::Tap tap(TimeUs epoch_us);

 private:
  std::unique_ptr<std::ostream> owned_;
  std::ostream* out_;
  std::string interface_;
};

}  // namespace pamc::canopen
