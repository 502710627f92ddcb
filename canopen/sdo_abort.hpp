// SDO abort codes (CiA 301, 7.2.4.3.17); also returned by object dictionary writes and application hooks.
#pragma once

#include <cstdint>

namespace pamc::canopen {

inline constexpr std::uint32_t kSdoOk = 0;
inline constexpr std::uint32_t kAbortToggleBit = 0x05030000;
inline constexpr std::uint32_t kAbortTimeout = 0x05040000;
inline constexpr std::uint32_t kAbortInvalidCommand = 0x05040001;
inline constexpr std::uint32_t kAbortOutOfMemory = 0x05040005;
inline constexpr std::uint32_t kAbortUnsupportedAccess = 0x06010000;
inline constexpr std::uint32_t kAbortWriteOnly = 0x06010001;  // attempt to read a write-only object
inline constexpr std::uint32_t kAbortReadOnly = 0x06010002;   // attempt to write a read-only object
inline constexpr std::uint32_t kAbortNoObject = 0x06020000;
inline constexpr std::uint32_t kAbortNotMappable = 0x06040041;
inline constexpr std::uint32_t kAbortPdoLength = 0x06040042;
inline constexpr std::uint32_t kAbortParameterIncompatible = 0x06040043;
inline constexpr std::uint32_t kAbortHardware = 0x06060000;
inline constexpr std::uint32_t kAbortLengthMismatch = 0x06070010;
inline constexpr std::uint32_t kAbortLengthTooHigh = 0x06070012;
inline constexpr std::uint32_t kAbortLengthTooLow = 0x06070013;
inline constexpr std::uint32_t kAbortNoSubIndex = 0x06090011;
inline constexpr std::uint32_t kAbortValueRange = 0x06090030;
inline constexpr std::uint32_t kAbortValueTooHigh = 0x06090031;
inline constexpr std::uint32_t kAbortValueTooLow = 0x06090032;
inline constexpr std::uint32_t kAbortGeneral = 0x08000000;
inline constexpr std::uint32_t kAbortCannotStore = 0x08000020;
inline constexpr std::uint32_t kAbortLocalControl = 0x08000021;
inline constexpr std::uint32_t kAbortDeviceState = 0x08000022;

// Short English text for logs and error messages; never null.
inline const char* sdoAbortText(std::uint32_t code) {
  switch (code) {
    case kSdoOk: return "no error";
    case kAbortToggleBit: return "toggle bit not alternated";
    case kAbortTimeout: return "SDO protocol timed out";
    case kAbortInvalidCommand: return "client/server command specifier not valid or unknown";
    case kAbortOutOfMemory: return "out of memory";
    case kAbortUnsupportedAccess: return "unsupported access to an object";
    case kAbortWriteOnly: return "attempt to read a write only object";
    case kAbortReadOnly: return "attempt to write a read only object";
    case kAbortNoObject: return "object does not exist in the object dictionary";
    case kAbortNotMappable: return "object cannot be mapped to the PDO";
    case kAbortPdoLength: return "number and length of mapped objects exceed PDO length";
    case kAbortParameterIncompatible: return "general parameter incompatibility";
    case kAbortHardware: return "access failed due to a hardware error";
    case kAbortLengthMismatch: return "data type does not match, length of service parameter does not match";
    case kAbortLengthTooHigh: return "data type does not match, length of service parameter too high";
    case kAbortLengthTooLow: return "data type does not match, length of service parameter too low";
    case kAbortNoSubIndex: return "sub-index does not exist";
    case kAbortValueRange: return "invalid value for parameter";
    case kAbortValueTooHigh: return "value of parameter written too high";
    case kAbortValueTooLow: return "value of parameter written too low";
    case kAbortGeneral: return "general error";
    case kAbortCannotStore: return "data cannot be transferred or stored to the application";
    case kAbortLocalControl: return "data cannot be transferred or stored because of local control";
    case kAbortDeviceState: return "data cannot be transferred or stored because of the present device state";
    default: return "unknown abort code";
  }
}

}  // namespace pamc::canopen
