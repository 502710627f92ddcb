#include "io/measurement.hpp"

#include <sys/stat.h>

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

namespace pamc::io {

namespace {

std::string trim(const std::string& s) {
  size_t a = 0, b = s.size();
  while (a < b && (s[a] == ' ' || s[a] == '\t' || s[a] == '\r' || s[a] == '"')) ++a;
  while (b > a && (s[b - 1] == ' ' || s[b - 1] == '\t' || s[b - 1] == '\r' || s[b - 1] == '"')) --b;
  return s.substr(a, b - a);
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  for (char ch : line) {
    if (ch == ',') {
      out.push_back(trim(cur));
      cur.clear();
    } else {
      cur += ch;
    }
  }
  out.push_back(trim(cur));
  return out;
}

[[noreturn]] void fail(const std::string& src, size_t line, const std::string& col, const std::string& what) {
  std::ostringstream os;
  os << src << ":" << line;
  if (!col.empty()) os << ": column '" << col << "'";
  os << ": " << what;
  throw InputError(os.str());
}

std::string s_of(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.9g", v);
  return b;
}

}  // namespace

Measurement Measurement::slice(size_t b, size_t e) const {
  Measurement m;
  m.source = source;
  m.Ts = Ts;
  e = std::min(e, size());
  auto cut = [&](const std::vector<double>& v) {
    return std::vector<double>(v.begin() + static_cast<long>(b), v.begin() + static_cast<long>(e));
  };
  m.t = cut(t);
  m.u = cut(u);
  m.y = cut(y);
  for (const auto& kv : extra) m.extra[kv.first] = cut(kv.second);
  return m;
}

Measurement Measurement::decimate(size_t step) const {
  if (step == 0) throw std::invalid_argument("decimate: the step must be at least 1");
  Measurement m;
  m.source = source;
  m.Ts = Ts * static_cast<double>(step);
  auto pick = [&](const std::vector<double>& v) {
    std::vector<double> r;
    r.reserve(v.size() / step + 1);
    for (size_t i = 0; i < v.size(); i += step) r.push_back(v[i]);
    return r;
  };
  m.t = pick(t);
  m.u = pick(u);
  m.y = pick(y);
  for (const auto& kv : extra) m.extra[kv.first] = pick(kv.second);
  return m;
}

Measurement parseMeasurementCsv(const std::string& text, const std::string& src, std::vector<std::string>* warnings) {
  Measurement m;
  m.source = src;
  std::vector<std::string> lines;
  {
    std::string cur;
    for (char ch : text) {
      if (ch == '\n') {
        lines.push_back(cur);
        cur.clear();
      } else {
        cur += ch;
      }
    }
    if (!cur.empty()) lines.push_back(cur);
  }
  const bool ends_with_newline = !text.empty() && text.back() == '\n';
  size_t li = 0;
  while (li < lines.size() && (trim(lines[li]).empty() || trim(lines[li])[0] == '#')) ++li;
  if (li >= lines.size()) fail(src, 1, "", "empty file: expected a header with columns t,u,y");
  const size_t header_line = li + 1;
  const auto header = split(lines[li]);
  int it = -1, iu = -1, iy = -1;
  for (size_t c = 0; c < header.size(); ++c) {
    const std::string& h = header[c];
    if (h.empty()) fail(src, header_line, "", "empty column name at position " + std::to_string(c + 1));
    for (size_t d = 0; d < c; ++d)
      if (header[d] == h) fail(src, header_line, h, "duplicate column");
    if (h == "t")
      it = static_cast<int>(c);
    else if (h == "u")
      iu = static_cast<int>(c);
    else if (h == "y")
      iy = static_cast<int>(c);
  }
  for (auto [idx, name] : {std::pair<int, const char*>{it, "t"}, {iu, "u"}, {iy, "y"}})
    if (idx < 0) fail(src, header_line, "", std::string("missing column '") + name + "' (the header needs t,u,y)");
  std::vector<std::vector<double>> cols(header.size());
  for (size_t l = li + 1; l < lines.size(); ++l) {
    const std::string tl = trim(lines[l]);
    if (tl.empty() || tl[0] == '#') continue;
    const auto cells = split(lines[l]);
    const bool last = l + 1 == lines.size();
    if (cells.size() != header.size()) {
      if (last && !ends_with_newline) {  // a record cut off by a crash of the writer
        if (warnings) warnings->push_back(src + ":" + std::to_string(l + 1) + ": truncated last line ignored");
        break;
      }
      fail(src, l + 1, "",
           "expected " + std::to_string(header.size()) + " fields, found " + std::to_string(cells.size()));
    }
    std::vector<double> row(header.size());
    bool truncated = false;
    for (size_t c = 0; c < cells.size(); ++c) {
      const std::string& s = cells[c];
      char* end = nullptr;
      errno = 0;
      const double v = s.empty() ? NAN : std::strtod(s.c_str(), &end);
      if (s.empty() || end != s.c_str() + s.size()) {
        if (last && !ends_with_newline) {
          truncated = true;
          break;
        }
        fail(src, l + 1, header[c], s.empty() ? "empty cell" : "not a number: '" + s + "'");
      }
      if (!std::isfinite(v)) fail(src, l + 1, header[c], "value is not finite: '" + s + "'");
      row[c] = v;
    }
    if (truncated) {
      if (warnings) warnings->push_back(src + ":" + std::to_string(l + 1) + ": truncated last line ignored");
      break;
    }
    for (size_t c = 0; c < row.size(); ++c) {
      if (static_cast<int>(c) == it) {
        if (std::fabs(row[c]) > kMaxTime)
          fail(src, l + 1, header[c],
               "time " + cells[c] + " s is out of range (|t| must be at most " + s_of(kMaxTime) + " s)");
      } else if (std::fabs(row[c]) > kMaxDataValue) {
        fail(src, l + 1, header[c],
             "value " + cells[c] + " is too large to identify a model from (|" + header[c] + "| must be at most " +
                 s_of(kMaxDataValue) + ")");
      }
    }
    // Time must increase with an even step.
    auto& tc = cols[static_cast<size_t>(it)];
    const double tv = row[static_cast<size_t>(it)];
    if (!tc.empty()) {
      const double dt = tv - tc.back();
      if (!(dt > 0))
        fail(src, l + 1, "t",
             "time does not increase (" + s_of(tc.back()) + " then " + cells[static_cast<size_t>(it)] + ")");
      if (tc.size() >= 2) {
        const double dt0 = (tc.back() - tc.front()) / static_cast<double>(tc.size() - 1);
        if (std::fabs(dt - dt0) > 0.02 * dt0 + 1e-12)
          fail(src, l + 1, "t", "uneven sampling step: " + s_of(dt) + " s after " + s_of(dt0) + " s");
      }
    }
    for (size_t c = 0; c < row.size(); ++c) cols[c].push_back(row[c]);
  }
  if (cols[static_cast<size_t>(it)].size() < 3) fail(src, header_line, "", "fewer than 3 data rows");
  m.t = std::move(cols[static_cast<size_t>(it)]);
  m.u = std::move(cols[static_cast<size_t>(iu)]);
  m.y = std::move(cols[static_cast<size_t>(iy)]);
  for (size_t c = 0; c < header.size(); ++c)
    if (static_cast<int>(c) != it && static_cast<int>(c) != iu && static_cast<int>(c) != iy)
      m.extra[header[c]] = std::move(cols[c]);
  m.Ts = (m.t.back() - m.t.front()) / static_cast<double>(m.t.size() - 1);
  if (!(m.Ts >= kMinSamplingStep))
    fail(src, header_line, "t", "sampling step " + s_of(m.Ts) + " s is below " + s_of(kMinSamplingStep) + " s");
  return m;
}

Measurement readMeasurementCsv(const std::string& path, std::vector<std::string>* warnings) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(path + ": cannot open file");
  std::ostringstream ss;
  ss << f.rdbuf();
  return parseMeasurementCsv(ss.str(), path, warnings);
}

namespace {

// write(2) the whole buffer (short writes, EINTR); false with errno on failure.
bool writeAll(int fd, const char* p, size_t n) {
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    p += w;
    n -= static_cast<size_t>(w);
  }
  return true;
}

// Content into fd, then onto the disk (fsync: the rename below must not reach the disk before the data).
bool writeAndSync(int fd, const std::string& content) {
  return writeAll(fd, content.data(), content.size()) && ::fsync(fd) == 0;
}

}  // namespace

void makeDirectory(const std::string& dir, const std::string& what) {
  ::mkdir(dir.c_str(), 0755);
  struct stat sb {};
  if (::stat(dir.c_str(), &sb) != 0 || !S_ISDIR(sb.st_mode))
    throw std::runtime_error(dir + ": cannot create the " + what);
}

void writeFileAtomic(const std::string& path, const std::string& content) {
  // First choice: an unnamed file in the target's directory (O_TMPFILE), given its name only when it is
  // complete. A crash or kill -9 during the write leaves nothing behind - no half-written file and no
  // temporary - because the kernel frees an unnamed file with its last descriptor.
  const auto slash = path.find_last_of('/');
  const std::string dir = slash == std::string::npos ? "." : slash == 0 ? "/" : path.substr(0, slash);
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  int fd = ::open(dir.c_str(), O_TMPFILE | O_WRONLY | O_CLOEXEC, 0666);
  if (fd >= 0) {
    if (!writeAndSync(fd, content)) {
      ::close(fd);
      throw std::runtime_error(path + ": write failed (" + std::strerror(errno) + ")");
    }
    char proc[64];
    std::snprintf(proc, sizeof proc, "/proc/self/fd/%d", fd);
    // No file there yet: link it in place directly (linkat never replaces one).
    if (::linkat(AT_FDCWD, proc, AT_FDCWD, path.c_str(), AT_SYMLINK_FOLLOW) == 0) {
      ::close(fd);
      return;
    }
    // A file to replace: link under a temporary name, then rename over it (atomic). Only between these
    // two calls does a named temporary exist.
    const bool linked = errno == EEXIST && ::linkat(AT_FDCWD, proc, AT_FDCWD, tmp.c_str(), AT_SYMLINK_FOLLOW) == 0;
    ::close(fd);
    if (linked) {
      if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        ::unlink(tmp.c_str());
        throw std::runtime_error(path + ": cannot rename temporary file into place");
      }
      return;
    }
    // No /proc, or the file system cannot link it: the named temporary below.
  }
  // Fallback (file systems without O_TMPFILE): a named temporary, written, synced and renamed.
  fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd < 0) throw std::runtime_error(path + ": cannot write (is the directory there and writable?)");
  if (!writeAndSync(fd, content)) {
    const int e = errno;
    ::close(fd);
    ::unlink(tmp.c_str());
    throw std::runtime_error(path + ": write failed (" + std::strerror(e) + ")");
  }
  ::close(fd);
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    ::unlink(tmp.c_str());
    throw std::runtime_error(path + ": cannot rename temporary file into place");
  }
}

void writeCsvAtomic(const std::string& path, const std::vector<std::string>& header,
                    const std::vector<const std::vector<double>*>& columns, int precision) {
  std::string out;
  for (size_t c = 0; c < header.size(); ++c) out += (c ? "," : "") + header[c];
  out += '\n';
  const size_t n = columns.empty() ? 0 : columns[0]->size();
  char buf[64];
  for (size_t i = 0; i < n; ++i) {
    for (size_t c = 0; c < columns.size(); ++c) {
      std::snprintf(buf, sizeof buf, "%s%.*g", c ? "," : "", precision, (*columns[c])[i]);
      out += buf;
    }
    out += '\n';
  }
  writeFileAtomic(path, out);
}

}  // namespace pamc::io
