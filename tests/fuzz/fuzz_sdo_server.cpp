// fuzz_sdo_server: sequences of SDO requests to the SDO server of one node built from od/*.eds -
// expedited and segmented download and upload, toggles right and wrong, client aborts, unsupported
// commands (block transfer), timeouts, NMT state changes and resets in the middle of a transfer.
//
// Input: byte 0: bits 0-1 the node (0 controller, 1 sensor, 2 valve, 3 kTransferEds below: writable
// strings and domains for long segmented transfers, which the rig's dictionaries do not have),
// bit 2 Operational from the start.
// Then operations, each an opcode byte op:
//   op & 7 == 0  initiate expedited download: entry, 4 data bytes; op bit 3: size indicated, bits 4-5: n
//   op & 7 == 1  initiate segmented download: entry; op bit 3: size indicated, bit 4: 32-bit size (else 8-bit)
//   op & 7 == 2  download segment: byte c (bit 0 last, bits 1-3 unused bytes n, bit 7 wrong toggle), 7 data bytes
//   op & 7 == 3  initiate upload: entry
//   op & 7 == 4  upload segment; op bit 3: wrong toggle
//   op & 7 == 5  any 8 bytes (also client abort and block transfer commands)
//   op & 7 == 6  time advances by (next 16 bits) * 100 us (the SDO timeout is 1 s)
//   op & 7 == 7  op bit 6 clear: NMT command ((op >> 3) & 7 picks one) to this node;
//                op bit 6 set: a request of (op >> 3) & 7 bytes (wrong length)
// An entry is one byte: below 0xF0 it picks one of the dictionary's entries, else index (16 bits) and
// sub-index (8 bits) follow.
//
// Properties checked besides crashes and sanitizer reports (a broken one aborts with "FINDING"):
//  - a well-formed request in Pre-operational/Operational gets exactly one 8-byte response on the
//    server's COB-ID (none for a client abort), and none in Stopped; no SDO frame at all in Stopped;
//  - abort codes are ones CiA 301 defines;
//  - segmented upload: segments only while an upload runs, their bytes add up to the indicated size,
//    and the last one is flagged;
//  - a confirmed download stored exactly the bytes sent.
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "canopen/eds_dictionary.hpp"
#include "canopen/node.hpp"
#include "fuzz_util.hpp"

using namespace pamc::canopen;
using pamc::fuzz::finding;

namespace {

// Node 9 with entries of every kind of length: strings, a domain, an octet string, 64-bit values,
// write-only and const entries, limits.
constexpr const char* kTransferEds = R"([FileInfo]
FileName=transfer.eds
EDSVersion=4.0
[DeviceInfo]
VendorName=pamc
ProductName=SDO transfer test
[DeviceComissioning]
NodeID=9
[MandatoryObjects]
SupportedObjects=3
1=0x1000
2=0x1001
3=0x1018
[OptionalObjects]
SupportedObjects=2
1=0x1008
2=0x1017
[ManufacturerObjects]
SupportedObjects=4
1=0x2000
2=0x2001
3=0x2002
4=0x2100
[1000]
ParameterName=Device type
DataType=0x0007
AccessType=ro
DefaultValue=0
[1001]
ParameterName=Error register
DataType=0x0005
AccessType=ro
DefaultValue=0
[1008]
ParameterName=Device name
DataType=0x0009
AccessType=const
DefaultValue=a device name longer than one segment
[1017]
ParameterName=Producer heartbeat time
DataType=0x0006
AccessType=rw
DefaultValue=0
[1018]
ParameterName=Identity
ObjectType=0x9
SubNumber=2
[1018sub0]
ParameterName=Highest sub-index
DataType=0x0005
AccessType=ro
DefaultValue=1
[1018sub1]
ParameterName=Vendor-ID
DataType=0x0007
AccessType=ro
DefaultValue=0
[2000]
ParameterName=Name
DataType=0x0009
AccessType=rw
DefaultValue=pamc
[2001]
ParameterName=Blob
DataType=0x000F
AccessType=rw
DefaultValue=00112233445566778899AABBCCDDEEFF
[2002]
ParameterName=Key
DataType=0x000A
AccessType=wo
DefaultValue=0102
[2100]
ParameterName=Values
ObjectType=0x9
SubNumber=5
[2100sub0]
ParameterName=Highest sub-index
DataType=0x0005
AccessType=ro
DefaultValue=4
[2100sub1]
ParameterName=Gain
DataType=0x0011
AccessType=rw
DefaultValue=1.5
LowLimit=-10
HighLimit=10
[2100sub2]
ParameterName=Counter
DataType=0x001B
AccessType=rw
DefaultValue=0
[2100sub3]
ParameterName=Offset
DataType=0x0015
AccessType=rww
DefaultValue=-1
[2100sub4]
ParameterName=Enable
DataType=0x0001
AccessType=rw
DefaultValue=0
)";

const std::array<EdsFile, 4>& dictionaries() {
  static const std::array<EdsFile, 4> eds = {
      EdsFile::load(PAMC_OD_DIR "/controller.eds"), EdsFile::load(PAMC_OD_DIR "/sensor.eds"),
      EdsFile::load(PAMC_OD_DIR "/valve.eds"), EdsFile::parse(kTransferEds, "transfer.eds")};
  return eds;
}

struct Recorder : Transport {
  std::vector<Frame> sent;
  bool send(const Frame& f) override {
    sent.push_back(f);
    return true;
  }
};

std::string hex(const Frame& f) {
  std::string s;
  char b[4];
  for (int i = 0; i < f.len && i < 8; ++i) {
    std::snprintf(b, sizeof b, "%02X", f.data[i]);
    s += b;
  }
  return s;
}

// What the client knows of the transfer in progress.
struct ClientModel {
  // Download: the bytes sent so far; compared with the entry when the server confirms the transfer.
  bool dl_tracked = false;
  std::uint16_t dl_index = 0;
  std::uint8_t dl_sub = 0;
  std::vector<std::uint8_t> dl_bytes;
  std::uint8_t dl_toggle = 0;
  // Upload: indicated size and bytes received.
  bool ul_active = false;
  std::size_t ul_size = 0;
  std::size_t ul_got = 0;
  std::uint8_t ul_toggle = 0;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  pamc::fuzz::Bytes in(data, size);
  const std::uint8_t setup = in.u8();
  const EdsFile& eds = dictionaries()[setup & 0x03];
  Recorder bus;
  NodeOptions options;
  options.auto_operational = (setup & 0x04) != 0;
  Node node(dictionaryFromEds(eds, eds.node_id), eds.node_id, bus, options);
  const std::vector<Entry>& entries = node.od().entries();
  const std::uint32_t rx = node.sdoServer().requestCobId();
  const std::uint32_t tx = node.sdoServer().responseCobId();
  TimeUs now = 0;
  node.start(now);
  ClientModel cm;
  static const bool trace = std::getenv("PAMC_FUZZ_TRACE") != nullptr;  // prints every exchange

  while (!in.empty()) {
    const std::uint8_t op = in.u8();
    bus.sent.clear();
    const bool communicating = node.nmtState() == NmtState::PreOperational || node.nmtState() == NmtState::Operational;
    Frame f = makeFrame(rx, 8);
    bool request = true;  // an 8-byte request to the server that expects one answer
    bool expect_store = false;

    auto entryRef = [&]() {
      const std::uint8_t e = in.u8();
      std::uint16_t index = 0;
      std::uint8_t sub = 0;
      if (e < 0xF0) {
        const Entry& en = entries[e % entries.size()];
        index = en.index();
        sub = en.subIndex();
      } else {
        index = in.u16();
        sub = in.u8();
      }
      putU16(f.data + 1, index);
      f.data[3] = sub;
    };

    switch (op & 0x07) {
      case 0: {
        entryRef();
        for (int i = 4; i < 8; ++i) f.data[i] = in.u8();
        const bool sized = (op & 0x08) != 0;
        const unsigned n = (op >> 4) & 0x03;
        f.data[0] = static_cast<std::uint8_t>(0x22 | (sized ? 0x01 | (n << 2) : 0));
        cm.dl_tracked = false;
        cm.ul_active = false;  // a new initiate replaces any transfer
        if (const Entry* e = node.od().find(getU16(f.data + 1), f.data[3])) {
          const std::size_t fixed = dataTypeSize(e->dataType());
          const std::size_t len = sized ? 4 - n : (fixed != 0 && fixed < 4 ? fixed : 4);
          cm.dl_tracked = true;
          cm.dl_index = e->index();
          cm.dl_sub = e->subIndex();
          cm.dl_bytes.assign(f.data + 4, f.data + 4 + len);
          expect_store = true;
        }
        break;
      }
      case 1: {
        entryRef();
        const bool sized = (op & 0x08) != 0;
        if (sized) putU32(f.data + 4, (op & 0x10) != 0 ? in.u32() : in.u8());
        f.data[0] = static_cast<std::uint8_t>(0x20 | (sized ? 0x01 : 0));
        cm.ul_active = false;
        cm.dl_tracked = true;
        cm.dl_index = getU16(f.data + 1);
        cm.dl_sub = f.data[3];
        cm.dl_bytes.clear();
        cm.dl_toggle = 0;
        break;
      }
      case 2: {
        const std::uint8_t c = in.u8();
        const std::uint8_t t = static_cast<std::uint8_t>(cm.dl_toggle ^ ((c >> 7) & 1));
        const unsigned n = (c >> 1) & 0x07;
        const bool last = (c & 0x01) != 0;
        f.data[0] = static_cast<std::uint8_t>((t << 4) | (n << 1) | (last ? 1 : 0));
        for (int i = 1; i < 8; ++i) f.data[i] = in.u8();
        cm.dl_toggle ^= 1;
        if (cm.dl_tracked) cm.dl_bytes.insert(cm.dl_bytes.end(), f.data + 1, f.data + 8 - n);
        expect_store = last;
        break;
      }
      case 3:
        entryRef();
        f.data[0] = 0x40;
        cm.dl_tracked = false;
        cm.ul_active = false;
        break;
      case 4:
        f.data[0] = static_cast<std::uint8_t>(0x60 | ((cm.ul_toggle ^ ((op >> 3) & 1)) << 4));
        cm.ul_toggle ^= 1;
        break;
      case 5:
        for (int i = 0; i < 8; ++i) f.data[i] = in.u8();
        request = (f.data[0] >> 5) != 4;  // a client abort gets no answer
        cm.dl_tracked = false;
        break;
      case 6:
        now += in.u16() * TimeUs{100};
        node.advance(now);
        request = false;
        f.len = 0;
        break;
      case 7:
        request = false;
        cm.dl_tracked = false;
        if ((op & 0x40) == 0) {
          static constexpr std::uint8_t kCommands[8] = {0x01, 0x02, 0x80, 0x81, 0x82, 0x01, 0x80, 0x82};
          f = makeFrame(0x000, 2);
          f.data[0] = kCommands[(op >> 3) & 0x07];
          f.data[1] = (op & 0x80) != 0 ? 0 : node.nodeId();
          // A reset, and a stop (no SDO in Stopped), drop the transfer.
          if (f.data[0] == 0x81 || f.data[0] == 0x82 || f.data[0] == 0x02) cm.ul_active = false;
        } else {
          f.len = (op >> 3) & 0x07;
          for (int i = 0; i < f.len; ++i) f.data[i] = in.u8();
        }
        break;
    }
    if (f.len != 0 || (op & 0x07) == 7) node.onFrame(f, now);
    if (trace) {
      std::fprintf(stderr, "t=%lld op=%02X %03X#%s ->", static_cast<long long>(now), op, static_cast<unsigned>(f.id),
                   hex(f).c_str());
      for (const Frame& r : bus.sent) std::fprintf(stderr, " %03X#%s", static_cast<unsigned>(r.id), hex(r).c_str());
      std::fprintf(stderr, "\n");
    }

    // ---- Properties of the answer ----
    std::size_t responses = 0;
    for (const Frame& r : bus.sent) {
      if (r.id != tx) continue;
      ++responses;
      if (r.len != 8) finding("SDO response of " + std::to_string(r.len) + " bytes");
      const std::uint8_t scs = r.data[0] >> 5;
      if (scs == 4) {
        const std::uint32_t code = getU32(r.data + 4);
        if (std::strcmp(sdoAbortText(code), "unknown abort code") == 0) {
          finding("SDO abort with an undefined code " + hex(r));
        }
        cm.ul_active = false;
        cm.dl_tracked = false;
        continue;
      }
      if (scs == 2 && (r.data[0] & 0x02) == 0) {  // segmented upload starts
        if ((r.data[0] & 0x01) == 0) finding("segmented upload without size: " + hex(r));
        cm.ul_active = true;
        cm.ul_size = getU32(r.data + 4);
        cm.ul_got = 0;
        cm.ul_toggle = 0;
      } else if (scs == 0) {  // upload segment
        if (!cm.ul_active) finding("upload segment without an upload in progress: " + hex(r));
        cm.ul_got += 7 - ((r.data[0] >> 1) & 0x07);
        const bool last = (r.data[0] & 0x01) != 0;
        if (cm.ul_got > cm.ul_size) finding("upload sent more bytes than it indicated: " + hex(r));
        if (last != (cm.ul_got == cm.ul_size)) finding("upload ended at the wrong segment: " + hex(r));
        if (last) cm.ul_active = false;
      }
      if (expect_store && cm.dl_tracked && (scs == 3 || scs == 1)) {
        const Entry* e = node.od().find(cm.dl_index, cm.dl_sub);
        if (e == nullptr) finding("download confirmed for an entry that does not exist");
        if (e->size() != cm.dl_bytes.size() ||
            (e->size() != 0 && std::memcmp(e->data(), cm.dl_bytes.data(), e->size()) != 0)) {
          finding("download confirmed but the entry does not hold the bytes sent: " + hex(f));
        }
        cm.dl_tracked = false;
      }
    }
    if (!communicating && (op & 0x07) == 6 && responses != 0) finding("SDO frame sent in NMT state Stopped");
    if (request && f.len == 8 && f.id == rx) {
      const std::size_t expected = communicating ? 1 : 0;
      if (responses != expected) {
        finding("request " + hex(f) + " got " + std::to_string(responses) + " responses, expected " +
                std::to_string(expected));
      }
    }
  }
  return 0;
}
