#include "canopen/od.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace pamc::canopen {

namespace {

// Strings get some room beyond their default so an SDO client can write a longer name.
constexpr std::size_t kMinStringCapacity = 32;
constexpr std::size_t kMinDomainCapacity = 256;

template <class T>
T load(const std::uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

bool isSigned(DataType t) {
  switch (t) {
    case DataType::Integer8:
    case DataType::Integer16:
    case DataType::Integer32:
    case DataType::Integer64: return true;
    default: return false;
  }
}

std::int64_t decodeSigned(DataType t, const std::uint8_t* p) {
  switch (t) {
    case DataType::Integer8: return load<std::int8_t>(p);
    case DataType::Integer16: return load<std::int16_t>(p);
    case DataType::Integer32: return load<std::int32_t>(p);
    case DataType::Integer64: return load<std::int64_t>(p);
    default: return 0;
  }
}

std::uint64_t decodeUnsigned(DataType t, const std::uint8_t* p) {
  switch (t) {
    case DataType::Boolean:
    case DataType::Unsigned8: return load<std::uint8_t>(p);
    case DataType::Unsigned16: return load<std::uint16_t>(p);
    case DataType::Unsigned32: return load<std::uint32_t>(p);
    case DataType::Unsigned64: return load<std::uint64_t>(p);
    default: return 0;
  }
}

double decodeReal(DataType t, const std::uint8_t* p) {
  if (t == DataType::Real32) return load<float>(p);
  if (t == DataType::Real64) return load<double>(p);
  return 0.0;
}

}  // namespace

int compareValues(DataType t, const std::uint8_t* a, const std::uint8_t* b, bool& unordered) {
  unordered = false;
  if (isSigned(t)) {
    auto x = decodeSigned(t, a), y = decodeSigned(t, b);
    return x < y ? -1 : (x > y ? 1 : 0);
  }
  if (t == DataType::Real32 || t == DataType::Real64) {
    double x = decodeReal(t, a), y = decodeReal(t, b);
    if (std::isnan(x) || std::isnan(y)) {
      unordered = true;
      return 0;
    }
    return x < y ? -1 : (x > y ? 1 : 0);
  }
  auto x = decodeUnsigned(t, a), y = decodeUnsigned(t, b);
  return x < y ? -1 : (x > y ? 1 : 0);
}

bool isSupportedDataType(std::uint16_t code) {
  switch (static_cast<DataType>(code)) {
    case DataType::Boolean:
    case DataType::Integer8:
    case DataType::Integer16:
    case DataType::Integer32:
    case DataType::Unsigned8:
    case DataType::Unsigned16:
    case DataType::Unsigned32:
    case DataType::Real32:
    case DataType::VisibleString:
    case DataType::OctetString:
    case DataType::Domain:
    case DataType::Real64:
    case DataType::Integer64:
    case DataType::Unsigned64: return true;
  }
  return false;
}

std::size_t dataTypeSize(DataType type) {
  switch (type) {
    case DataType::Boolean:
    case DataType::Integer8:
    case DataType::Unsigned8: return 1;
    case DataType::Integer16:
    case DataType::Unsigned16: return 2;
    case DataType::Integer32:
    case DataType::Unsigned32:
    case DataType::Real32: return 4;
    case DataType::Real64:
    case DataType::Integer64:
    case DataType::Unsigned64: return 8;
    case DataType::VisibleString:
    case DataType::OctetString:
    case DataType::Domain: return 0;
  }
  return 0;
}

bool isNumeric(DataType type) { return dataTypeSize(type) != 0; }

const char* dataTypeName(DataType type) {
  switch (type) {
    case DataType::Boolean: return "BOOLEAN";
    case DataType::Integer8: return "INTEGER8";
    case DataType::Integer16: return "INTEGER16";
    case DataType::Integer32: return "INTEGER32";
    case DataType::Unsigned8: return "UNSIGNED8";
    case DataType::Unsigned16: return "UNSIGNED16";
    case DataType::Unsigned32: return "UNSIGNED32";
    case DataType::Real32: return "REAL32";
    case DataType::VisibleString: return "VISIBLE_STRING";
    case DataType::OctetString: return "OCTET_STRING";
    case DataType::Domain: return "DOMAIN";
    case DataType::Real64: return "REAL64";
    case DataType::Integer64: return "INTEGER64";
    case DataType::Unsigned64: return "UNSIGNED64";
  }
  return "?";
}

const char* accessName(Access access) {
  switch (access) {
    case Access::ReadOnly: return "ro";
    case Access::WriteOnly: return "wo";
    case Access::ReadWrite: return "rw";
    case Access::ReadWriteRead: return "rwr";
    case Access::ReadWriteWrite: return "rww";
    case Access::Const: return "const";
  }
  return "?";
}

std::string entryName(std::uint16_t index, std::uint8_t sub) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%04X:%02X", static_cast<unsigned>(index), static_cast<unsigned>(sub));
  return buf;
}

// ---- Entry ----

bool Entry::write(const std::uint8_t* bytes, std::size_t len) {
  std::size_t fixed = dataTypeSize(type_);
  if (fixed != 0 ? len != fixed : len > capacity_) return false;
  std::memcpy(value_, bytes, len);
  size_ = len;
  return true;
}

std::uint64_t Entry::asUnsigned() const {
  if (isSigned(type_)) return static_cast<std::uint64_t>(decodeSigned(type_, value_));
  return decodeUnsigned(type_, value_);
}

std::int64_t Entry::asSigned() const {
  if (isSigned(type_)) return decodeSigned(type_, value_);
  return static_cast<std::int64_t>(decodeUnsigned(type_, value_));
}

bool Entry::highLimit(std::int64_t& out) const {
  if (!has_high_ || type_ == DataType::Real32 || type_ == DataType::Real64) return false;
  out = isSigned(type_) ? decodeSigned(type_, high_) : static_cast<std::int64_t>(decodeUnsigned(type_, high_));
  return true;
}

double Entry::asDouble() const {
  if (type_ == DataType::Real32 || type_ == DataType::Real64) return decodeReal(type_, value_);
  if (isSigned(type_)) return static_cast<double>(decodeSigned(type_, value_));
  return static_cast<double>(decodeUnsigned(type_, value_));
}

// ---- ObjectDictionary ----

ObjectDictionary::ObjectDictionary(std::vector<ObjectInfo> objects, std::vector<EntrySpec> specs) {
  std::sort(specs.begin(), specs.end(), [](const EntrySpec& a, const EntrySpec& b) {
    return a.index != b.index ? a.index < b.index : a.sub < b.sub;
  });
  for (std::size_t i = 1; i < specs.size(); ++i) {
    if (specs[i].index == specs[i - 1].index && specs[i].sub == specs[i - 1].sub) {
      throw OdError("duplicate object dictionary entry " + entryName(specs[i].index, specs[i].sub));
    }
  }

  entries_.resize(specs.size());
  std::size_t total = 0;
  for (std::size_t i = 0; i < specs.size(); ++i) {
    EntrySpec& s = specs[i];
    Entry& e = entries_[i];
    e.index_ = s.index;
    e.sub_ = s.sub;
    e.name_ = std::move(s.name);
    e.type_ = s.type;
    e.access_ = s.access;
    e.pdo_mappable_ = s.pdo_mappable;
    std::size_t fixed = dataTypeSize(s.type);
    if (fixed != 0) {
      if (s.default_value.empty()) s.default_value.assign(fixed, 0);
      if (s.default_value.size() != fixed) {
        throw OdError("default value of " + entryName(s.index, s.sub) + " has the wrong size");
      }
      e.capacity_ = fixed;
      if (s.low_limit.size() == fixed) {
        e.has_low_ = true;
        std::memcpy(e.low_, s.low_limit.data(), fixed);
      }
      if (s.high_limit.size() == fixed) {
        e.has_high_ = true;
        std::memcpy(e.high_, s.high_limit.data(), fixed);
      }
    } else {
      std::size_t min_cap = s.type == DataType::Domain ? kMinDomainCapacity : kMinStringCapacity;
      e.capacity_ = std::max(s.default_value.size(), min_cap);
    }
    e.default_size_ = s.default_value.size();
    e.size_ = e.default_size_;
    e.offset_ = total;
    total += (e.capacity_ + 7) & ~std::size_t{7};  // 8-byte slots keep every value aligned
    max_size_ = std::max(max_size_, e.capacity_);
  }
  values_.assign(total, 0);
  defaults_.assign(total, 0);
  for (std::size_t i = 0; i < specs.size(); ++i) {
    Entry& e = entries_[i];
    const std::vector<std::uint8_t>& def = specs[i].default_value;
    if (!def.empty()) {  // an empty string/domain default has no data pointer to copy from
      std::memcpy(&defaults_[e.offset_], def.data(), def.size());
      std::memcpy(&values_[e.offset_], def.data(), def.size());
    }
    e.value_ = values_.data() + e.offset_;
    e.default_ = defaults_.data() + e.offset_;
  }

  std::sort(objects.begin(), objects.end(), [](const ObjectInfo& a, const ObjectInfo& b) { return a.index < b.index; });
  // Entries without an explicit object description become VAR objects.
  for (std::size_t i = 0; i < entries_.size();) {
    std::uint16_t idx = entries_[i].index_;
    std::size_t j = i;
    while (j < entries_.size() && entries_[j].index_ == idx) ++j;
    auto it = std::lower_bound(objects.begin(), objects.end(), idx,
                               [](const ObjectInfo& o, std::uint16_t v) { return o.index < v; });
    if (it == objects.end() || it->index != idx) {
      ObjectInfo info;
      info.index = idx;
      info.name = entries_[i].name_;
      it = objects.insert(it, info);
    }
    it->first = i;
    it->count = j - i;
    i = j;
  }
  objects.erase(std::remove_if(objects.begin(), objects.end(), [](const ObjectInfo& o) { return o.count == 0; }),
                objects.end());
  objects_ = std::move(objects);
}

Entry* ObjectDictionary::find(std::uint16_t index, std::uint8_t sub) {
  return const_cast<Entry*>(static_cast<const ObjectDictionary*>(this)->find(index, sub));
}

const Entry* ObjectDictionary::find(std::uint16_t index, std::uint8_t sub) const {
  std::uint32_t key = (static_cast<std::uint32_t>(index) << 8) | sub;
  auto it = std::lower_bound(entries_.begin(), entries_.end(), key, [](const Entry& e, std::uint32_t k) {
    return ((static_cast<std::uint32_t>(e.index_) << 8) | e.sub_) < k;
  });
  if (it == entries_.end() || it->index_ != index || it->sub_ != sub) return nullptr;
  return &*it;
}

Entry& ObjectDictionary::entry(std::uint16_t index, std::uint8_t sub) {
  Entry* e = find(index, sub);
  if (e == nullptr) throw OdError("object dictionary has no entry " + entryName(index, sub));
  return *e;
}

const ObjectInfo* ObjectDictionary::object(std::uint16_t index) const {
  auto it = std::lower_bound(objects_.begin(), objects_.end(), index,
                             [](const ObjectInfo& o, std::uint16_t v) { return o.index < v; });
  if (it == objects_.end() || it->index != index) return nullptr;
  return &*it;
}

void ObjectDictionary::throwTypeMismatch(const Entry& e) {
  throw OdError("entry " + entryName(e.index(), e.subIndex()) + " (" + e.name() + ") is " + dataTypeName(e.dataType()) +
                ", not the requested C++ type");
}

void ObjectDictionary::addValidator(std::uint16_t index, std::uint8_t sub, WriteValidator v) {
  entry(index, sub).validators_.push_back(std::move(v));
}

void ObjectDictionary::addValidator(std::uint16_t index, WriteValidator v) {
  const ObjectInfo* o = object(index);
  if (o == nullptr) throw OdError("object dictionary has no object " + entryName(index, 0).substr(0, 6));
  for (std::size_t i = o->first; i < o->first + o->count; ++i) entries_[i].validators_.push_back(v);
}

void ObjectDictionary::addObserver(std::uint16_t index, std::uint8_t sub, WriteObserver o) {
  entry(index, sub).observers_.push_back(std::move(o));
}

void ObjectDictionary::addObserver(std::uint16_t index, WriteObserver obs) {
  const ObjectInfo* o = object(index);
  if (o == nullptr) throw OdError("object dictionary has no object " + entryName(index, 0).substr(0, 6));
  for (std::size_t i = o->first; i < o->first + o->count; ++i) entries_[i].observers_.push_back(obs);
}

std::uint32_t ObjectDictionary::remoteWrite(Entry& e, const std::uint8_t* data, std::size_t len) {
  if (!e.writable()) return kAbortReadOnly;
  std::uint32_t code = checkValue(e, data, len);
  if (code != kSdoOk) return code;
  for (const WriteValidator& v : e.validators_) {
    code = v(e, data, len);
    if (code != kSdoOk) return code;
  }
  std::memcpy(e.value_, data, len);
  e.size_ = len;
  for (const WriteObserver& o : e.observers_) o(e);
  return kSdoOk;
}

std::uint32_t ObjectDictionary::checkValue(const Entry& e, const std::uint8_t* data, std::size_t len) const {
  std::size_t fixed = dataTypeSize(e.type_);
  if (fixed != 0) {
    if (len > fixed) return kAbortLengthTooHigh;
    if (len < fixed) return kAbortLengthTooLow;
    bool unordered = false;
    if (e.has_low_) {
      if (compareValues(e.type_, data, e.low_, unordered) < 0) return kAbortValueTooLow;
      if (unordered) return kAbortValueRange;
    }
    if (e.has_high_) {
      if (compareValues(e.type_, data, e.high_, unordered) > 0) return kAbortValueTooHigh;
      if (unordered) return kAbortValueRange;
    }
    if (e.type_ == DataType::Boolean && data[0] > 1) return kAbortValueRange;
  } else if (len > e.capacity_) {
    return kAbortLengthTooHigh;
  }
  return kSdoOk;
}

std::uint32_t ObjectDictionary::remoteRead(const Entry& e, std::uint8_t* out, std::size_t cap, std::size_t& len) const {
  if (!e.readable()) return kAbortWriteOnly;
  len = e.size_;
  std::memcpy(out, e.value_, std::min(cap, e.size_));
  return kSdoOk;
}

void ObjectDictionary::restoreDefaults(std::uint16_t first, std::uint16_t last) {
  for (Entry& e : entries_) {
    if (e.index_ < first || e.index_ > last) continue;
    std::memcpy(e.value_, e.default_, e.default_size_);
    e.size_ = e.default_size_;
  }
}

}  // namespace pamc::canopen
