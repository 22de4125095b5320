// The single entry point of aos._core: version, exception translation, the Python progress sink,
// and one BindX(m) call per binding file.
#include <algorithm>
#include <exception>
#include <filesystem>
#include <thread>
#include <vector>

#include "aos/util/error.h"
#include "aos/util/progress.h"
#include "aos/util/version.h"
#include "bindings.h"

namespace aos::python {

PythonProgress::PythonProgress(py::object callback) : owner_(std::this_thread::get_id()) {
  if (!callback.is_none()) {
    if (!PyCallable_Check(callback.ptr())) {
      throw py::type_error("progress must be None or a callable progress(stage, done, total)");
    }
    callback_ = std::move(callback);
  }
}

PythonProgress::~PythonProgress() = default;

void PythonProgress::Start(const std::string& stage, int64_t total) {
  {
    std::lock_guard<std::mutex> lock(stage_mutex_);
    stage_ = stage;
  }
  total_.store(total);
  done_.store(0);
  if (std::this_thread::get_id() == owner_) {
    final_reported_ = false;
    Report(/*force=*/true);
  }
}

void PythonProgress::Advance(int64_t units) {
  done_.fetch_add(units);
  if (std::this_thread::get_id() == owner_) Report(/*force=*/false);
}

bool PythonProgress::Cancelled() {
  if (std::this_thread::get_id() == owner_) Report(/*force=*/false);
  return failed_.load();
}

void PythonProgress::Finish() {
  const int64_t total = total_.load();
  if (!failed_.load() && !final_reported_ && total > 0 && done_.load() >= total) Report(true);
  RethrowIfFailed();
}

void PythonProgress::RethrowIfFailed() {
  if (!error_) return;
  py::error_already_set error = std::move(*error_);
  error_.reset();
  throw error;
}

void PythonProgress::Report(bool force) {
  if (failed_.load()) return;
  const int64_t total = total_.load();
  const int64_t done = done_.load();
  const bool finished = done >= total;
  const auto now = std::chrono::steady_clock::now();
  if (finished && !final_reported_) {
    force = true;  // the one report with done == total
  }
  if (!force && now - last_report_ < kReportInterval) return;
  last_report_ = now;
  if (finished) final_reported_ = true;

  py::gil_scoped_acquire gil;
  if (PyErr_CheckSignals() != 0) {  // e.g. KeyboardInterrupt from Ctrl-C
    error_.emplace();
    failed_.store(true);
    return;
  }
  if (!callback_) return;
  std::string stage;
  {
    std::lock_guard<std::mutex> lock(stage_mutex_);
    stage = stage_;
  }
  try {
    callback_(stage, done, total);
  } catch (py::error_already_set& error) {
    error_.emplace(std::move(error));
    failed_.store(true);
  }
}

void WarnDeprecated(const std::string& message) {
  // Level 1 from C is the Python frame that called into the binding: the user's code.
  if (PyErr_WarnEx(PyExc_DeprecationWarning, message.c_str(), 1) < 0) throw py::error_already_set();
}

bool ValuesEqual(const py::handle& a, const py::handle& b) {
  const py::module_ numpy = py::module_::import("numpy");
  const py::object ndarray = numpy.attr("ndarray");
  if (py::isinstance(a, ndarray) || py::isinstance(b, ndarray)) {
    return numpy.attr("array_equal")(a, b).cast<bool>();
  }
  const int equal = PyObject_RichCompareBool(a.ptr(), b.ptr(), Py_EQ);
  if (equal < 0) throw py::error_already_set();
  return equal == 1;
}

py::dict StateDict(const py::handle& state, const std::string& class_name,
                   const std::vector<std::string>& keys) {
  if (!py::isinstance<py::dict>(state)) {
    throw py::value_error(class_name + ": pickled state must be a dict, got " +
                          std::string(py::str(py::type::handle_of(state).attr("__name__"))));
  }
  py::dict dict = py::reinterpret_borrow<py::dict>(state);
  for (const std::string& key : keys) {
    if (!dict.contains(py::str(key))) {
      throw py::value_error(class_name + ": pickled state has no '" + key +
                            "' (written by another aos version?)");
    }
  }
  for (const auto& item : dict) {
    const std::string key = py::str(item.first);
    if (std::find(keys.begin(), keys.end(), key) == keys.end()) {
      throw py::value_error(class_name + ": pickled state has an unknown key '" + key +
                            "' (written by another aos version?)");
    }
  }
  return dict;
}

namespace {

// Test hook for the progress plumbing (not public API): `total` units of fake work shared by the
// calling thread and num_threads - 1 std::threads, each unit sleeping `sleep_us`, following the
// ProgressSink contract of the algorithms (Start on the caller, Advance from any thread, poll
// Cancelled, throw aos::Cancelled after the workers joined). Returns the units done.
int64_t ProgressSelfTest(int64_t total, int num_threads, int sleep_us, ProgressSink* sink,
                         bool throw_cancelled) {
  if (throw_cancelled) throw Cancelled();
  ProgressStart(sink, "selftest", total);
  std::atomic<int64_t> next{0};
  std::atomic<int64_t> done{0};
  std::atomic<bool> stop{false};
  auto work = [&](bool caller) {
    while (!stop.load()) {
      if (next.fetch_add(1) >= total) break;
      if (sleep_us > 0) std::this_thread::sleep_for(std::chrono::microseconds(sleep_us));
      ProgressAdvance(sink, 1);
      done.fetch_add(1);
      if (caller && ProgressCancelled(sink)) stop.store(true);
    }
  };
  std::vector<std::thread> workers;
  for (int i = 1; i < num_threads; ++i) workers.emplace_back(work, false);
  work(true);
  for (std::thread& worker : workers) worker.join();
  if (ProgressCancelled(sink)) throw Cancelled();
  return done.load();
}

}  // namespace

}  // namespace aos::python

PYBIND11_MODULE(_core, m) {
  namespace py = pybind11;
  using namespace aos::python;
  m.doc() =
      "Native core of aos (Airborne Optical Sectioning): geometry, images, light fields, "
      "integral rendering. Use the `aos` package; its docs state the numpy copy rules.";
  m.attr("__version__") = aos::kVersion;

  // std::invalid_argument -> ValueError is pybind11's default. Cancellation from a progress sink
  // (Ctrl-C) becomes KeyboardInterrupt.
  py::register_exception_translator([](std::exception_ptr pointer) {
    try {
      if (pointer) std::rethrow_exception(pointer);
    } catch (const aos::Cancelled& error) {
      PyErr_SetString(PyExc_KeyboardInterrupt, error.what());
    } catch (const std::filesystem::filesystem_error& error) {
      // A path the filesystem refused is bad input like any other: ValueError, one line.
      PyErr_SetString(PyExc_ValueError, aos::OneLine(error.what()).c_str());
    }
  });

  BindGeometry(m);
  BindImage(m);
  BindLightField(m);
  BindRender(m);
  BindMetrics(m);
  BindSim(m);
  BindCalib(m);
  BindSfm(m);
  BindDemo(m);
  BindPlan(m);
  BindDetect(m);

  m.def(
      "_progress_selftest",
      [](int64_t total, int num_threads, int sleep_us, const py::object& progress,
         bool throw_cancelled) {
        return RunWithProgress(progress, [&](aos::ProgressSink* sink) {
          return ProgressSelfTest(total, num_threads, sleep_us, sink, throw_cancelled);
        });
      },
      py::arg("total"), py::arg("num_threads") = 2, py::arg("sleep_us") = 0,
      py::arg("progress") = py::none(), py::arg("throw_cancelled") = false,
      "Test hook for the progress sink (not public API).");
}
