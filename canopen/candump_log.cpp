#include "canopen/candump_log.hpp"

#include <cctype>
#include <cinttypes>
#include <cstdio>
#include <fstream>
#include <istream>
#include <ostream>
#include <stdexcept>

namespace pamc::canopen {

namespace {

constexpr std::uint32_t kErrFlag = 0x20000000;  // CAN_ERR_FLAG as candump prints it
constexpr char kHex[] = "0123456789ABCDEF";

int hexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

bool setError(std::string* error, const char* text) {
  if (error != nullptr) *error = text;
  return false;
}

}  // namespace

std::string formatFrame(const Frame& f) {
  char buf[40];
  int n = 0;
  if (f.error()) {
    n = std::snprintf(buf, sizeof buf, "%08" PRIX32 "#", (f.id & kExtendedIdMask) | kErrFlag);
  } else if (f.extended()) {
    n = std::snprintf(buf, sizeof buf, "%08" PRIX32 "#", f.id & kExtendedIdMask);
  } else {
    n = std::snprintf(buf, sizeof buf, "%03" PRIX32 "#", f.id & kStandardIdMask);
  }
  std::string s(buf, static_cast<std::size_t>(n));
  if (f.remote()) {
    s += 'R';
    if (f.len > 0) s += kHex[f.len & 0x0F];  // newer can-utils print the DLC of a remote frame
    return s;
  }
  for (std::uint8_t i = 0; i < f.len && i < 8; ++i) {
    s += kHex[f.data[i] >> 4];
    s += kHex[f.data[i] & 0x0F];
  }
  return s;
}

std::string formatCandumpLine(const Frame& f, TimeUs unix_time_us, std::string_view interface) {
  char ts[48];
  std::snprintf(ts, sizeof ts, "(%" PRId64 ".%06" PRId64 ") ", unix_time_us / 1000000, unix_time_us % 1000000);
  std::string line(ts);
  line.append(interface);
  line += ' ';
  line += formatFrame(f);
  return line;
}

bool parseFrame(std::string_view token, Frame& out, std::string* error) {
  out = Frame{};
  std::size_t hash = token.find('#');
  if (hash == std::string_view::npos) return setError(error, "frame has no '#'");
  std::string_view id = token.substr(0, hash);
  std::string_view data = token.substr(hash + 1);
  if (!data.empty() && data.front() == '#') return setError(error, "CAN FD frames (##) are not supported");
  if (id.size() != 3 && id.size() != 8) return setError(error, "identifier must have 3 or 8 hex digits");
  std::uint32_t v = 0;
  for (char c : id) {
    int h = hexValue(c);
    if (h < 0) return setError(error, "identifier is not hexadecimal");
    v = (v << 4) | static_cast<std::uint32_t>(h);
  }
  if (id.size() == 3) {
    if (v > kStandardIdMask) return setError(error, "11-bit identifier above 7FF");
    out.id = v;
  } else if ((v & kErrFlag) != 0) {
    out.id = v & ~kErrFlag & kExtendedIdMask;
    out.flags |= kFrameError;
  } else {
    if (v > kExtendedIdMask) return setError(error, "29-bit identifier above 1FFFFFFF");
    out.id = v;
    out.flags |= kFrameExtended;
  }
  if (!data.empty() && (data.front() == 'R' || data.front() == 'r')) {
    out.flags |= kFrameRemote;
    if (data.size() == 2) {
      int dlc = hexValue(data[1]);
      if (dlc < 0 || dlc > 8) return setError(error, "remote frame DLC must be 0..8");
      out.len = static_cast<std::uint8_t>(dlc);
    } else if (data.size() > 2) {
      return setError(error, "unexpected characters after R");
    }
    return true;
  }
  std::uint8_t len = 0;
  for (std::size_t i = 0; i < data.size();) {
    if (data[i] == '.') {  // cansend-style byte separator
      ++i;
      continue;
    }
    if (i + 1 >= data.size()) return setError(error, "odd number of hex digits in data");
    int hi = hexValue(data[i]), lo = hexValue(data[i + 1]);
    if (hi < 0 || lo < 0) return setError(error, "data is not hexadecimal");
    if (len == 8) return setError(error, "more than 8 data bytes");
    out.data[len++] = static_cast<std::uint8_t>((hi << 4) | lo);
    i += 2;
  }
  out.len = len;
  return true;
}

bool parseCandumpLine(std::string_view line, CandumpRecord& out, std::string* error) {
  auto skipSpace = [&](std::size_t& i) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
  };
  std::size_t i = 0;
  skipSpace(i);
  if (i >= line.size() || line[i] != '(') return setError(error, "line does not start with '(timestamp)'");
  ++i;
  std::int64_t sec = 0;
  std::size_t digits = 0;
  while (i < line.size() && std::isdigit(static_cast<unsigned char>(line[i]))) {
    if (++digits > 12) return setError(error, "timestamp seconds have more than 12 digits");
    sec = sec * 10 + (line[i++] - '0');
  }
  if (digits == 0 || i >= line.size() || line[i] != '.') return setError(error, "bad timestamp seconds");
  ++i;
  std::int64_t frac = 0;
  std::size_t frac_digits = 0;
  while (i < line.size() && std::isdigit(static_cast<unsigned char>(line[i]))) {
    if (frac_digits < 6) frac = frac * 10 + (line[i] - '0');
    ++frac_digits;
    ++i;
  }
  if (frac_digits == 0 || i >= line.size() || line[i] != ')') return setError(error, "bad timestamp fraction");
  for (std::size_t d = frac_digits; d < 6; ++d) frac *= 10;
  ++i;
  skipSpace(i);
  std::size_t start = i;
  while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
  if (i == start) return setError(error, "missing interface name");
  std::string_view iface = line.substr(start, i - start);
  skipSpace(i);
  start = i;
  while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
  if (i == start) return setError(error, "missing frame");
  Frame f;
  if (!parseFrame(line.substr(start, i - start), f, error)) return false;
  out.unix_time_us = sec * 1000000 + frac;
  out.interface.assign(iface.begin(), iface.end());
  out.frame = f;
  return true;
}

std::vector<CandumpRecord> readCandumpLog(std::istream& in, const std::string& name,
                                          std::vector<std::string>* warnings) {
  std::vector<CandumpRecord> records;
  std::string line;
  int lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    // getline stops at the end of the input without a newline: the last line was cut off (a writer
    // killed in the middle of it). Every writer of the format ends each line with one, and a cut line
    // may still parse (a frame cut in its data bytes), so it is dropped whatever it holds.
    if (in.eof()) {
      if (line.find_first_not_of(" \t\r") != std::string::npos && warnings != nullptr)
        warnings->push_back(name + ":" + std::to_string(lineno) +
                            ": truncated last line ignored (no newline at the end)");
      break;
    }
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.find_first_not_of(" \t") == std::string::npos) continue;
    CandumpRecord r;
    std::string err;
    if (!parseCandumpLine(line, r, &err)) {
      throw std::runtime_error(name + ":" + std::to_string(lineno) + ": " + err);
    }
    records.push_back(std::move(r));
  }
  return records;
}

std::vector<CandumpRecord> readCandumpLog(const std::string& path, std::vector<std::string>* warnings) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open candump log");
  return readCandumpLog(in, path, warnings);
}

CandumpWriter::CandumpWriter(const std::string& path, std::string interface)
    : owned_(std::make_unique<std::ofstream>(path, std::ios::trunc)),
      out_(owned_.get()),
      interface_(std::move(interface)) {
  if (!*owned_) throw std::runtime_error(path + ": cannot create candump log");
}

CandumpWriter::CandumpWriter(std::ostream& out, std::string interface) : out_(&out), interface_(std::move(interface)) {}

CandumpWriter::~CandumpWriter() {
  if (out_ != nullptr) out_->flush();
}

void CandumpWriter::write(const Frame& f, TimeUs unix_time_us) {
  *out_ << formatCandumpLine(f, unix_time_us, interface_) << '\n';
}

void CandumpWriter::flush() { out_->flush(); }

VirtualBus::Tap CandumpWriter::tap(TimeUs epoch_us) {
  return [this, epoch_us](const Frame& f, TimeUs now) { write(f, epoch_us + now); };
}

}  // namespace pamc::canopen
