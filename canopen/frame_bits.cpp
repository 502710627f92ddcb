#include "canopen/frame_bits.hpp"

namespace pamc::canopen {

namespace {

inline constexpr std::uint16_t kCrc15Poly = 0x4599;  // x^15 + x^14 + x^10 + x^8 + x^7 + x^4 + x^3 + 1

// The transmitter's bit stream from SOF to the end of the CRC sequence, fed one field at a time: it
// runs the CRC register over the bits up to the data field and counts the bits sent with stuffing, so
// the frame is never materialised.
class StuffedStream {
 public:
  // A field that goes into the CRC (SOF through data), MSB first as on the wire.
  void field(std::uint32_t value, unsigned width) {
    for (unsigned i = width; i-- > 0;) {
      const bool bit = ((value >> i) & 1u) != 0;
      crcStep(bit);
      send(bit);
    }
  }
  // The CRC sequence closes the stuffed region; it is stuffed too, including a stuff bit after its
  // last bit when that ends a run of 5.
  void crcSequence() {
    const std::uint16_t crc = crc_;
    for (unsigned i = 15; i-- > 0;) send(((crc >> i) & 1u) != 0);
  }
  unsigned bits() const { return bits_; }

 private:
  // Textbook CRC-15 shift register (initial value 0, as in the CAN specification).
  void crcStep(bool bit) {
    const bool feedback = bit != (((crc_ >> 14) & 1u) != 0);
    crc_ = static_cast<std::uint16_t>((crc_ << 1) & 0x7FFFu);
    if (feedback) crc_ ^= kCrc15Poly;
  }
  // One bit on the wire; the stuff bit it forces starts the next run (it counts toward it).
  void send(bool bit) {
    ++bits_;
    run_ = (run_ > 0 && bit == last_) ? run_ + 1 : 1;
    last_ = bit;
    if (run_ == 5) {
      ++bits_;
      last_ = !bit;
      run_ = 1;
    }
  }
  std::uint16_t crc_ = 0;
  unsigned bits_ = 0;
  unsigned run_ = 0;
  bool last_ = false;
};

// Base format: SOF, 11-bit id, RTR, IDE (dominant), r0, DLC.
void standardHeader(StuffedStream& s, const Frame& f, unsigned dlc) {
  s.field(0, 1);
  s.field(f.id & kStandardIdMask, 11);
  s.field(f.remote() ? 1 : 0, 1);
  s.field(0, 2);  // IDE, r0
  s.field(dlc, 4);
}

// Extended format: SOF, base id (top 11 bits), SRR and IDE (recessive), 18-bit id extension, RTR, r1, r0,
// DLC.
void extendedHeader(StuffedStream& s, const Frame& f, unsigned dlc) {
  const std::uint32_t id = f.id & kExtendedIdMask;
  s.field(0, 1);
  s.field(id >> 18, 11);
  s.field(0x3, 2);  // SRR, IDE
  s.field(id & 0x3FFFFu, 18);
  s.field(f.remote() ? 1 : 0, 1);
  s.field(0, 2);  // r1, r0
  s.field(dlc, 4);
}

}  // namespace

unsigned frameBits(const Frame& f) {
  if (f.error()) return kErrorFrameBits;
  const unsigned dlc = f.len > 8 ? 8u : f.len;
  StuffedStream s;
  if (f.extended()) {
    extendedHeader(s, f, dlc);
  } else {
    standardHeader(s, f, dlc);
  }
  if (!f.remote()) {
    for (unsigned i = 0; i < dlc; ++i) s.field(f.data[i], 8);
  }
  s.crcSequence();
  return s.bits() + kFrameTailBits + kIntermissionBits;
}

}  // namespace pamc::canopen
