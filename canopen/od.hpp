// Object dictionary (CiA 301, 7.4): entries built once from an EDS file, storage allocated at configuration time.
#pragma once

#include <cassert>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "canopen/sdo_abort.hpp"

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__,
              "OD storage is little-endian like the CANopen wire format; big-endian hosts are not supported");

namespace pamc::canopen {

// Basic data types (CiA 301, 7.4.7.1); the numeric values are the EDS DataType codes.
enum class DataType : std::uint16_t {
  Boolean = 0x0001,
  Integer8 = 0x0002,
  Integer16 = 0x0003,
  Integer32 = 0x0004,
  Unsigned8 = 0x0005,
  Unsigned16 = 0x0006,
  Unsigned32 = 0x0007,
  Real32 = 0x0008,
  VisibleString = 0x0009,
  OctetString = 0x000A,
  Domain = 0x000F,
  Real64 = 0x0011,
  Integer64 = 0x0015,
  Unsigned64 = 0x001B,
};

enum class ObjectType : std::uint8_t { Var = 0x7, Array = 0x8, Record = 0x9 };

// EDS AccessType values; rwr/rww are read-write over SDO, the suffix only hints the PDO direction.
enum class Access : std::uint8_t { ReadOnly, WriteOnly, ReadWrite, ReadWriteRead, ReadWriteWrite, Const };

// True if code is one of the DataType values above.
bool isSupportedDataType(std::uint16_t code);
// Fixed size in bytes, or 0 for the variable-length string/domain types.
std::size_t dataTypeSize(DataType type);
bool isNumeric(DataType type);
const char* dataTypeName(DataType type);
const char* accessName(Access access);
// Compares two encoded numeric values of one type like strcmp; unordered is set for a NaN operand.
int compareValues(DataType type, const std::uint8_t* a, const std::uint8_t* b, bool& unordered);

// Maps a C++ type to the data types it may read or write (checked when a Ref is made).
template <class T>
constexpr bool dataTypeMatches(DataType t) {
  if constexpr (std::is_same_v<T, bool>)
    return t == DataType::Boolean;
  else if constexpr (std::is_same_v<T, std::int8_t>)
    return t == DataType::Integer8;
  else if constexpr (std::is_same_v<T, std::int16_t>)
    return t == DataType::Integer16;
  else if constexpr (std::is_same_v<T, std::int32_t>)
    return t == DataType::Integer32;
  else if constexpr (std::is_same_v<T, std::int64_t>)
    return t == DataType::Integer64;
  else if constexpr (std::is_same_v<T, std::uint8_t>)
    return t == DataType::Unsigned8 || t == DataType::Boolean;
  else if constexpr (std::is_same_v<T, std::uint16_t>)
    return t == DataType::Unsigned16;
  else if constexpr (std::is_same_v<T, std::uint32_t>)
    return t == DataType::Unsigned32;
  else if constexpr (std::is_same_v<T, std::uint64_t>)
    return t == DataType::Unsigned64;
  else if constexpr (std::is_same_v<T, float>)
    return t == DataType::Real32;
  else if constexpr (std::is_same_v<T, double>)
    return t == DataType::Real64;
  else
    return false;
}

// Thrown while configuring (unknown entry, wrong type); never on the cyclic path.
class OdError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Entry;
// Runs before a remote (SDO) write is stored: return kSdoOk to accept, or an abort code to refuse.
using WriteValidator = std::function<std::uint32_t(const Entry& entry, const std::uint8_t* data, std::size_t len)>;
// Runs after a remote write was stored; e.g. set a flag and apply the value at a safe point (the SYNC callback).
using WriteObserver = std::function<void(Entry& entry)>;

// One sub-index of an object. Pointers to entries stay valid for the life of the dictionary.
class Entry {
 public:
  std::uint16_t index() const { return index_; }
  std::uint8_t subIndex() const { return sub_; }
  DataType dataType() const { return type_; }
  Access access() const { return access_; }
  bool pdoMappable() const { return pdo_mappable_; }
  const std::string& name() const { return name_; }
  std::size_t size() const { return size_; }          // current length in bytes
  std::size_t capacity() const { return capacity_; }  // storage reserved at configuration
  const std::uint8_t* data() const { return value_; }
  bool readable() const { return access_ != Access::WriteOnly; }
  bool writable() const { return access_ != Access::ReadOnly && access_ != Access::Const; }

  // Typed access without lookup; T must match the data type (use ObjectDictionary::ref to check once).
  template <class T>
  T get() const {
    static_assert(std::is_arithmetic_v<T>, "get<T> needs an arithmetic type");
    assert(dataTypeMatches<T>(type_));
    T v{};
    std::memcpy(&v, value_, sizeof(T));
    return v;
  }
  // Local (application) write: no access check and no hooks, the application owns its values.
  template <class T>
  void set(T v) {
    static_assert(std::is_arithmetic_v<T>, "set<T> needs an arithmetic type");
    assert(dataTypeMatches<T>(type_));
    std::memcpy(value_, &v, sizeof(T));
  }
  // Raw local write; false (and nothing written) if len does not fit the entry.
  bool write(const std::uint8_t* bytes, std::size_t len);
  // Text of a VISIBLE_STRING entry.
  std::string_view str() const { return {reinterpret_cast<const char*>(value_), size_}; }
  // Reads any integer entry widened to 64 bits (0 for non-integers); handy for communication parameters.
  std::uint64_t asUnsigned() const;
  std::int64_t asSigned() const;
  double asDouble() const;
  // The EDS's HighLimit of an integer entry (what a device says its full scale is); false if none.
  bool highLimit(std::int64_t& out) const;

 private:
  friend class ObjectDictionary;
  std::uint16_t index_ = 0;
  std::uint8_t sub_ = 0;
  DataType type_ = DataType::Unsigned8;
  Access access_ = Access::ReadOnly;
  bool pdo_mappable_ = false;
  bool has_low_ = false;
  bool has_high_ = false;
  std::uint8_t low_[8] = {};
  std::uint8_t high_[8] = {};
  std::string name_;
  std::size_t size_ = 0;
  std::size_t capacity_ = 0;
  std::size_t default_size_ = 0;
  std::size_t offset_ = 0;
  std::uint8_t* value_ = nullptr;
  const std::uint8_t* default_ = nullptr;
  std::vector<WriteValidator> validators_;
  std::vector<WriteObserver> observers_;
};

// Typed handle resolved once at configuration; get/set are a memcpy.
template <class T>
class Ref {
 public:
  Ref() = default;
  explicit Ref(Entry* e) : entry_(e) {}
  T get() const { return entry_->get<T>(); }
  void set(T v) const { entry_->set<T>(v); }
  Entry& entry() const { return *entry_; }
  explicit operator bool() const { return entry_ != nullptr; }

 private:
  Entry* entry_ = nullptr;
};

struct ObjectInfo {
  std::uint16_t index = 0;
  ObjectType type = ObjectType::Var;
  std::string name;
  std::size_t first = 0;  // position of its first entry in entries()
  std::size_t count = 0;
};

// Description of one entry used to build a dictionary (filled from an EDS file).
struct EntrySpec {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::string name;
  DataType type = DataType::Unsigned8;
  Access access = Access::ReadOnly;
  bool pdo_mappable = false;
  std::vector<std::uint8_t> default_value;
  std::vector<std::uint8_t> low_limit;   // empty: no limit
  std::vector<std::uint8_t> high_limit;  // empty: no limit
};

class ObjectDictionary {
 public:
  ObjectDictionary(std::vector<ObjectInfo> objects, std::vector<EntrySpec> specs);
  ObjectDictionary(ObjectDictionary&&) noexcept = default;
  ObjectDictionary& operator=(ObjectDictionary&&) noexcept = default;
  ObjectDictionary(const ObjectDictionary&) = delete;
  ObjectDictionary& operator=(const ObjectDictionary&) = delete;

  // Lookup by binary search; nullptr if absent. Resolve once at configuration, keep the pointer.
  Entry* find(std::uint16_t index, std::uint8_t sub);
  const Entry* find(std::uint16_t index, std::uint8_t sub) const;
  // Like find but throws OdError naming the entry.
  Entry& entry(std::uint16_t index, std::uint8_t sub);
  const ObjectInfo* object(std::uint16_t index) const;
  bool hasObject(std::uint16_t index) const { return object(index) != nullptr; }

  // Typed handle; throws OdError if the entry is missing or its data type is not T.
  template <class T>
  Ref<T> ref(std::uint16_t index, std::uint8_t sub) {
    Entry& e = entry(index, sub);
    if (!dataTypeMatches<T>(e.dataType())) throwTypeMismatch(e);
    return Ref<T>(&e);
  }

  // Hooks for remote writes (SDO). sub omitted: every sub-index of the object. Throws OdError if absent.
  void addValidator(std::uint16_t index, std::uint8_t sub, WriteValidator v);
  void addValidator(std::uint16_t index, WriteValidator v);
  void addObserver(std::uint16_t index, std::uint8_t sub, WriteObserver o);
  void addObserver(std::uint16_t index, WriteObserver o);
  // Typed validator: fn(value) returns kSdoOk or an abort code, e.g. kAbortValueRange.
  template <class T, class Fn>
  void validate(std::uint16_t index, std::uint8_t sub, Fn fn) {
    Entry& e = entry(index, sub);
    if (!dataTypeMatches<T>(e.dataType())) throwTypeMismatch(e);
    addValidator(index, sub, [fn](const Entry&, const std::uint8_t* data, std::size_t len) -> std::uint32_t {
      if (len != sizeof(T)) return kAbortLengthMismatch;
      T v;
      std::memcpy(&v, data, sizeof(T));
      return fn(v);
    });
  }

  // Remote write as the SDO server does it: access, length, EDS limits, validators, store, observers.
  // Returns kSdoOk or the abort code. No allocation.
  std::uint32_t remoteWrite(Entry& e, const std::uint8_t* data, std::size_t len);
  // The checks of remoteWrite that need no hook: length, EDS limits, boolean range (not the access).
  // Lets an application check values it set locally against the same rules. No allocation.
  std::uint32_t checkValue(const Entry& e, const std::uint8_t* data, std::size_t len) const;
  // Remote read: checks access, copies at most cap bytes; len gets the entry size.
  std::uint32_t remoteRead(const Entry& e, std::uint8_t* out, std::size_t cap, std::size_t& len) const;

  // Restores the EDS default values of all entries with first <= index <= last (NMT reset).
  void restoreDefaults(std::uint16_t first, std::uint16_t last);

  const std::vector<Entry>& entries() const { return entries_; }
  const std::vector<ObjectInfo>& objects() const { return objects_; }
  std::size_t maxEntrySize() const { return max_size_; }

 private:
  [[noreturn]] static void throwTypeMismatch(const Entry& e);
  std::vector<ObjectInfo> objects_;
  std::vector<Entry> entries_;
  std::vector<std::uint8_t> values_;
  std::vector<std::uint8_t> defaults_;
  std::size_t max_size_ = 0;
};

// Helper for messages: "0x1017:00".
std::string entryName(std::uint16_t index, std::uint8_t sub);

}  // namespace pamc::canopen
