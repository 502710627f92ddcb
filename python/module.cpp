// The Python module pamc._pamc (docs/PYTHON.md); pamc/__init__.py re-exports it.
#include "bind.hpp"
#include "convert.hpp"

PYBIND11_MODULE(_pamc, m) {
  m.doc() = "pamc: model, identification, diagnosis and control of a pneumatic artificial muscle";
  pamc::python::registerExceptions();
  pamc::python::bindModel(m);
  pamc::python::bindAnalysis(m);
  pamc::python::bindLoop(m);
  pamc::python::bindSweep(m);
}
