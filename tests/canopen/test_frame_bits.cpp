// frameBits against a reference written independently of it: the frame as a string of '0'/'1', the
// CRC by polynomial long division on that string, stuffing by looking at the last five bits sent.
#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <string>

#include "canopen/frame_bits.hpp"

namespace pamc::canopen::test {
namespace {

// value as width bits, MSB first.
std::string bitString(std::uint32_t value, unsigned width) {
  std::string s;
  for (unsigned i = 0; i < width; ++i) s += ((value >> (width - 1 - i)) & 1u) ? '1' : '0';
  return s;
}

// CRC-15 as the remainder of (message * x^15) divided by the generator x^15+x^14+x^10+x^8+x^7+x^4+x^3+1,
// done as long division on the string.
std::string crc15(const std::string& message) {
  const std::string generator = "1100010110011001";
  std::string r = message + std::string(15, '0');
  for (std::size_t i = 0; i + 15 < r.size(); ++i) {
    if (r[i] != '1') continue;
    for (std::size_t j = 0; j < generator.size(); ++j) r[i + j] = r[i + j] == generator[j] ? '0' : '1';
  }
  return r.substr(r.size() - 15);
}

// The bits as sent: after any five equal bits at the end of what has been sent (stuff bits included), the
// complement goes out.
std::string stuff(const std::string& bits) {
  std::string out;
  for (char c : bits) {
    out += c;
    if (out.size() >= 5 && out.substr(out.size() - 5) == std::string(5, c)) out += c == '0' ? '1' : '0';
  }
  return out;
}

// SOF through the data field, destuffed.
std::string frameHead(const Frame& f) {
  const unsigned dlc = f.len > 8 ? 8 : f.len;
  const std::string rtr = f.remote() ? "1" : "0";
  std::string s = "0";  // SOF
  if (f.extended()) {
    const std::uint32_t id = f.id & 0x1FFFFFFF;
    s += bitString(id >> 18, 11) + "11" + bitString(id & 0x3FFFF, 18) + rtr + "00";  // SRR IDE .. RTR r1 r0
  } else {
    s += bitString(f.id & 0x7FF, 11) + rtr + "00";  // RTR IDE r0
  }
  s += bitString(dlc, 4);
  if (!f.remote()) {
    for (unsigned i = 0; i < dlc; ++i) s += bitString(f.data[i], 8);
  }
  return s;
}

unsigned referenceBits(const Frame& f) {
  const std::string head = frameHead(f);
  // CRC delimiter, ACK slot (recessive as the transmitter sends it), ACK delimiter, EOF, intermission.
  const std::string wire = stuff(head + crc15(head)) + "1" + "1" + "1" + "1111111" + "111";
  return static_cast<unsigned>(wire.size());
}

Frame randomFrame(std::mt19937& rng) {
  Frame f;
  const std::uint32_t kind = rng() % 4;
  const bool remote = (kind & 2u) != 0 && rng() % 4 == 0;  // 1 frame in 8 a remote frame
  f.flags = static_cast<std::uint8_t>(((kind & 1u) != 0 ? kFrameExtended : 0) | (remote ? kFrameRemote : 0));
  f.id = rng() & (f.extended() ? kExtendedIdMask : kStandardIdMask);
  f.len = static_cast<std::uint8_t>(rng() % 9);
  // A third of the frames with runs of equal bytes (0x00/0xFF, long runs to stuff), the rest random.
  const std::uint32_t style = rng() % 3;
  for (auto& b : f.data) {
    b = style == 0 ? static_cast<std::uint8_t>(rng() % 2 ? 0x00 : 0xFF) : static_cast<std::uint8_t>(rng());
  }
  if (rng() % 8 == 0) f.id &= 0x7u;  // mostly zero identifiers: long dominant runs from SOF
  return f;
}

Frame frameOf(std::uint32_t id, std::initializer_list<std::uint8_t> bytes, std::uint8_t flags = 0) {
  Frame f;
  f.id = id;
  f.flags = flags;
  for (std::uint8_t b : bytes) f.data[f.len++] = b;
  return f;
}

TEST(FrameBits, ReferenceIsTheTextbookCrc) {
  // The reference itself: a message followed by its CRC leaves no remainder, and the SYNC's CRC is the
  // one a bitwise shift register (a separate script) gives.
  const std::string head = frameHead(frameOf(0x080, {}));
  EXPECT_EQ(head,
            "0"
            "00010000000"
            "0"
            "00"
            "0000");
  EXPECT_EQ(crc15(head), "001110000000101");
  EXPECT_EQ(crc15(head + crc15(head)), std::string(15, '0'));
}

TEST(FrameBits, MatchesTheBitStringReferenceOnRandomFrames) {
  std::mt19937 rng(20261129);
  unsigned mismatches = 0;
  for (int i = 0; i < 20000; ++i) {
    const Frame f = randomFrame(rng);
    const unsigned expected = referenceBits(f);
    const unsigned got = frameBits(f);
    if (got != expected && ++mismatches <= 5) {
      ADD_FAILURE() << "id " << std::hex << f.id << " flags " << unsigned(f.flags) << std::dec << " len "
                    << unsigned(f.len) << ": frameBits " << got << ", reference " << expected;
    }
  }
  EXPECT_EQ(mismatches, 0u);
}

TEST(FrameBits, EveryDataLengthAndKindOfAllZeroAndAllOneFrames) {
  const std::uint8_t kinds[] = {0, kFrameExtended, kFrameRemote, kFrameExtended | kFrameRemote};
  for (std::uint8_t flags : kinds) {
    for (std::uint32_t id : {0u, 0x7FFu, 0x1FFFFFFFu, 0x555u, 0x0AAAAAAAu}) {
      for (std::uint8_t len = 0; len <= 8; ++len) {
        for (std::uint8_t fill : {std::uint8_t{0x00}, std::uint8_t{0xFF}, std::uint8_t{0x0F}}) {
          Frame f;
          f.id = id & ((flags & kFrameExtended) ? kExtendedIdMask : kStandardIdMask);
          f.flags = flags;
          f.len = len;
          for (auto& b : f.data) b = fill;
          EXPECT_EQ(frameBits(f), referenceBits(f)) << std::hex << f.id << " flags " << unsigned(flags) << std::dec
                                                    << " len " << unsigned(len) << " fill " << unsigned(fill);
        }
      }
    }
  }
}

TEST(FrameBits, StayWithinTheUnstuffedLengthAndTheStuffingBound) {
  // Stuff bits: at most one per 4 bits after the first 5 of the stuffed region (34 + 8n standard, 54 + 8n
  // extended; 47 + 8n and 67 + 8n with tail and intermission).
  std::mt19937 rng(7);
  for (int i = 0; i < 5000; ++i) {
    const Frame f = randomFrame(rng);
    const unsigned n = f.remote() ? 0 : f.len;
    const unsigned stuffed_region = (f.extended() ? 54 : 34) + 8 * n;
    const unsigned bits = frameBits(f);
    EXPECT_GE(bits, stuffed_region + 13);
    EXPECT_LE(bits, stuffed_region + 13 + (stuffed_region - 1) / 4);
  }
  EXPECT_GE(frameBits(frameOf(0x7FF, {})), 47u);
}

TEST(FrameBits, ZerosStuffHeavily) {
  // id 0, 8 bytes of 0x00: SOF, id, RTR, IDE, r0 are 15 dominant bits (3 stuff bits), DLC 1000 then
  // the data are 67 dominant bits (13 stuff bits); the CRC 001010001011011 adds none after the 2 zeros
  // left over. 47 + 64 + 16.
  const Frame f = frameOf(0x000, {0, 0, 0, 0, 0, 0, 0, 0});
  const unsigned bits = frameBits(f);
  EXPECT_EQ(bits, 127u);
  EXPECT_EQ(bits, referenceBits(f));
  EXPECT_LE(bits, 47u + 64u + (34u + 64u - 1u) / 4u);
}

TEST(FrameBits, CanopenSamples) {
  // The same counts from a separate bit-string script and from can-utils' exact mode (canframelen.c,
  // cfl_exact). SYNC: 34 + 13 bits and 4 stuff bits (3 in the 16 dominant bits from the id's last 7 into the CRC, 1
  // in the CRC's 7 zeros).
  EXPECT_EQ(frameBits(frameOf(0x080, {})), 51u);
  EXPECT_EQ(frameBits(frameOf(0x201, {0, 1, 2, 3, 4, 5, 6, 7})), 122u);  // 111 + 11 stuff bits
  EXPECT_EQ(frameBits(frameOf(0x181, {0x10, 0x27, 0x00, 0x00})), 86u);   // 79 + 7 stuff bits
}

TEST(FrameBits, ErrorFramesCountTheirFlagAndDelimiter) {
  Frame f = frameOf(0x004, {0, 0, 0, 0, 0, 0, 0, 0}, kFrameError);
  EXPECT_EQ(frameBits(f), 17u);
}

TEST(BusLoadMeter, AccumulatesBitsAndFrames) {
  BusLoadMeter m;
  EXPECT_EQ(m.bits(), 0u);
  EXPECT_EQ(m.load(1.0, 1'000'000), 0.0);
  const Frame sync = frameOf(0x080, {});
  const Frame pdo = frameOf(0x201, {0, 1, 2, 3, 4, 5, 6, 7});
  for (int i = 0; i < 1000; ++i) {
    m.add(sync);
    m.add(pdo);
  }
  EXPECT_EQ(m.frames(), 2000u);
  EXPECT_EQ(m.bits(), 1000u * (frameBits(sync) + frameBits(pdo)));
  // 1000 cycles in 1 s at 500 kbit/s.
  EXPECT_DOUBLE_EQ(m.load(1.0, 500'000), static_cast<double>(m.bits()) / 500'000.0);
  EXPECT_EQ(m.load(0.0, 500'000), 0.0);
  EXPECT_EQ(m.load(1.0, 0), 0.0);
  m.reset();
  EXPECT_EQ(m.bits(), 0u);
  EXPECT_EQ(m.frames(), 0u);
}

}  // namespace
}  // namespace pamc::canopen::test
