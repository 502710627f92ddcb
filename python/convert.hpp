// What the bindings share: numpy arrays to and from the library's vectors, JSON to and from Python
// objects, paths, and the exception that becomes FileNotFoundError.
#pragma once

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

namespace pamc::python {

namespace py = pybind11;

// A float64 C-contiguous view of an array: no copy when the input is one already.
using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;

// A file that is not there (raised as FileNotFoundError with the library's one-line message).
class MissingFile : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A str or os.PathLike as a path.
std::string pathOf(const py::handle& p);

bool fileExists(const std::string& path);

// Runs read(), which reads `path`; when it throws and the file is not there, the same message is
// thrown as MissingFile.
template <class F>
auto readingFile(const std::string& path, F&& read) -> decltype(read()) {
  try {
    return read();
  } catch (const std::exception& e) {
    if (!fileExists(path)) throw MissingFile(e.what());
    throw;
  }
}

// A 1-D array's samples (`what` names it in the error on another shape).
std::vector<double> toVector(const Array& a, const char* what);
// The vector as a numpy array that owns it (moved, not copied).
py::array_t<double> toArray(std::vector<double>&& v);
// A numpy view of v, kept alive by `owner`.
py::array_t<double> viewOf(const std::vector<double>& v, const py::handle& owner);

// nlohmann::json <-> Python (dict, list, str, float, int, bool, None), through Python's json module.
py::object toPython(const nlohmann::json& j);
nlohmann::json fromPython(const py::handle& o);

// Registers the module's exception translation: InputError and nlohmann's errors as ValueError,
// MissingFile as FileNotFoundError (std::invalid_argument is ValueError already).
void registerExceptions();

}  // namespace pamc::python
