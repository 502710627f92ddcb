#include "canopen/concise_dcf.hpp"

namespace pamc::canopen {

namespace {
void put(std::vector<std::uint8_t>& out, std::uint64_t v, std::size_t bytes) {
  for (std::size_t i = 0; i < bytes; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
std::uint64_t get(const std::uint8_t* p, std::size_t bytes) {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < bytes; ++i) v |= static_cast<std::uint64_t>(p[i]) << (8 * i);
  return v;
}
}  // namespace

DcfEntry dcfValue(std::uint16_t index, std::uint8_t sub, std::uint64_t value, std::size_t bytes) {
  DcfEntry e{index, sub, {}};
  put(e.data, value, bytes);
  return e;
}

std::vector<std::uint8_t> encodeConciseDcf(const ConciseDcf& dcf) {
  std::vector<std::uint8_t> out;
  put(out, dcf.size(), 4);
  for (const auto& e : dcf) {
    put(out, e.index, 2);
    put(out, e.sub, 1);
    put(out, e.data.size(), 4);
    out.insert(out.end(), e.data.begin(), e.data.end());
  }
  return out;
}

bool decodeConciseDcf(const std::uint8_t* data, std::size_t len, ConciseDcf& out, std::string* why) {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  out.clear();
  if (len < 4) return fail("shorter than its entry count (4 bytes)");
  const std::uint64_t n = get(data, 4);
  std::size_t at = 4;
  for (std::uint64_t i = 0; i < n; ++i) {
    const std::string where = "entry " + std::to_string(i + 1) + " of " + std::to_string(n);
    if (len - at < 7) return fail(where + ": header beyond the end");
    DcfEntry e;
    e.index = static_cast<std::uint16_t>(get(data + at, 2));
    e.sub = data[at + 2];
    const std::uint64_t size = get(data + at + 3, 4);
    at += 7;
    if (size > len - at) return fail(where + ": size " + std::to_string(size) + " beyond the end");
    e.data.assign(data + at, data + at + size);
    at += static_cast<std::size_t>(size);
    out.push_back(std::move(e));
  }
  if (at != len) return fail(std::to_string(len - at) + " bytes after the last entry");
  return true;
}

}  // namespace pamc::canopen
