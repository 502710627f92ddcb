// Shared helpers of the libFuzzer targets: a reader for structured binary inputs, the check of the
// project's error-message rule, a file view of the input for readers that take a path, and the bus
// helpers of the CANopen targets.
#pragma once

#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "canopen/bus.hpp"
#include "canopen/frame.hpp"

namespace pamc::fuzz {

// Reads a fuzz input front to back; past the end every read returns 0.
class Bytes {
 public:
  Bytes(const std::uint8_t* data, std::size_t size) : p_(data), n_(size) {}
  bool empty() const { return n_ == 0; }
  std::size_t left() const { return n_; }
  std::uint8_t u8() {
    if (n_ == 0) return 0;
    --n_;
    return *p_++;
  }
  std::uint16_t u16() {
    const unsigned lo = u8();
    return static_cast<std::uint16_t>(lo | (static_cast<unsigned>(u8()) << 8));
  }
  std::uint32_t u32() {
    const std::uint32_t lo = u16();
    return lo | (static_cast<std::uint32_t>(u16()) << 16);
  }

 private:
  const std::uint8_t* p_;
  std::size_t n_;
};

// A finding that is not a crash (a broken property): prints it and aborts, so libFuzzer keeps the input.
[[noreturn]] inline void finding(const std::string& what) {
  std::fprintf(stderr, "FINDING: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}

// Project rule: bad input yields a one-line error that names the place (the source first, if given)
// and the problem.
inline void checkMessage(const char* what, std::string_view source) {
  const std::string_view m(what);
  if (m.find('\n') != std::string_view::npos) finding("error message of more than one line: " + std::string(m));
  if (!source.empty() && m.compare(0, source.size(), source) != 0) {
    finding("error message does not start with the source " + std::string(source) + ": " + std::string(m));
  }
  if (m.size() < source.size() + 4) finding("error message names no problem: " + std::string(m));
}

// The input as a file, for readers that only take a path: an anonymous memory file opened by name
// through /proc/self/fd (no files left behind, whatever way the run ends).
class InputFile {
 public:
  InputFile() {
    fd_ = ::memfd_create("pamc-fuzz", 0);
    if (fd_ < 0) {
      std::perror("memfd_create");
      std::abort();
    }
    path_ = "/proc/self/fd/" + std::to_string(fd_);
  }
  const std::string& write(const std::uint8_t* data, std::size_t size) {
    if (::ftruncate(fd_, 0) != 0 || (size > 0 && ::pwrite(fd_, data, size, 0) != static_cast<ssize_t>(size))) {
      std::perror("memfd write");
      std::abort();
    }
    return path_;
  }
  const std::string& path() const { return path_; }

 private:
  int fd_ = -1;
  std::string path_;
};

// A frame from the input: identifier given by the caller, then one byte with the DLC (low nibble,
// capped at 8) and, if bit 7 is set, the SocketCAN flags in bits 4-6, then the data bytes.
inline canopen::Frame readFrame(Bytes& in, std::uint32_t id) {
  canopen::Frame f;
  f.id = id & canopen::kStandardIdMask;
  const std::uint8_t b = in.u8();
  f.len = static_cast<std::uint8_t>((b & 0x0F) > 8 ? 8 : (b & 0x0F));
  if ((b & 0x80) != 0) {
    f.flags = static_cast<std::uint8_t>((b >> 4) & 0x07);
    if (f.extended()) f.id = (id * 0x10001u) & canopen::kExtendedIdMask;
  }
  for (std::uint8_t i = 0; i < f.len; ++i) f.data[i] = in.u8();
  return f;
}

}  // namespace pamc::fuzz
