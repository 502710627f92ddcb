#include "convert.hpp"

#include <sys/stat.h>

#include "io/measurement.hpp"

namespace pamc::python {

std::string pathOf(const py::handle& p) { return py::str(py::module_::import("os").attr("fspath")(p)); }

bool fileExists(const std::string& path) {
  struct stat sb {};
  return ::stat(path.c_str(), &sb) == 0;
}

std::vector<double> toVector(const Array& a, const char* what) {
  if (a.ndim() != 1)
    throw std::invalid_argument(std::string(what) + ": a 1-D array is needed, got " + std::to_string(a.ndim()) +
                                " dimensions");
  return std::vector<double>(a.data(), a.data() + a.size());
}

py::array_t<double> toArray(std::vector<double>&& v) {
  auto* owned = new std::vector<double>(std::move(v));
  py::capsule free_it(owned, [](void* p) { delete static_cast<std::vector<double>*>(p); });
  return py::array_t<double>(static_cast<py::ssize_t>(owned->size()), owned->data(), free_it);
}

py::array_t<double> viewOf(const std::vector<double>& v, const py::handle& owner) {
  return py::array_t<double>(static_cast<py::ssize_t>(v.size()), v.data(), owner);
}

py::object toPython(const nlohmann::json& j) { return py::module_::import("json").attr("loads")(j.dump()); }

nlohmann::json fromPython(const py::handle& o) {
  return nlohmann::json::parse(py::str(py::module_::import("json").attr("dumps")(o)).cast<std::string>());
}

void registerExceptions() {
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const MissingFile& e) {
      PyErr_SetString(PyExc_FileNotFoundError, e.what());
    } catch (const io::InputError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const nlohmann::json::exception& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });
}

}  // namespace pamc::python
