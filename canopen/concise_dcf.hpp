#pragma once
// Concise DCF (CiA 302-3): the values a master writes into a slave at its boot, as one byte string -
// the number of entries (UNSIGNED32), then per entry index (UNSIGNED16), sub-index (UNSIGNED8), size
// in bytes (UNSIGNED32) and the value, all little-endian. Object 0x1F22 carries it per node-ID.
#include <cstdint>
#include <string>
#include <vector>

namespace pamc::canopen {

struct DcfEntry {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::vector<std::uint8_t> data;
  bool operator==(const DcfEntry& o) const { return index == o.index && sub == o.sub && data == o.data; }
};
using ConciseDcf = std::vector<DcfEntry>;

// An entry holding an unsigned value of `bytes` bytes.
DcfEntry dcfValue(std::uint16_t index, std::uint8_t sub, std::uint64_t value, std::size_t bytes);

std::vector<std::uint8_t> encodeConciseDcf(const ConciseDcf& dcf);
// False with why set ("entry 3 of 5: size 9 beyond the end", ...) on a malformed string.
bool decodeConciseDcf(const std::uint8_t* data, std::size_t len, ConciseDcf& out, std::string* why);

}  // namespace pamc::canopen
