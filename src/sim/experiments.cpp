#include "sim/experiments.hpp"

#include <sys/stat.h>

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "estimation/active_model.hpp"
#include "io/measurement.hpp"
#include "io/model_file.hpp"
#include "io/text.hpp"
#include "model/inverse_fold.hpp"
#include "report/figures.hpp"
#include "sim/experiment_steps.hpp"
#include "sim/paper_claims.hpp"

namespace pamc::sim {

namespace detail {

using io::fmt;

void Context::log(const std::string& m) const {
  if (s.log) s.log(m);
}

Record Context::run(control::Kind kind, const ClosedLoopRun& run, const std::string& tag,
                    const control::ControllerConfig* c, const std::string& csv_name) const {
  Record r = runController(kind, c ? *c : cc, inv, s.plant, run);
  r.writeCsv(dir + (csv_name.empty() ? tag + "_" + control::toString(kind) : csv_name) + ".csv");
  return r;
}

std::string esoText(const control::ControllerConfig& c) {
  if (c.eso.order == 1)
    return "ESO first-order (pamc's own) gain " + fmt("%g", c.eso.gain) + " mm/V tau " + fmt("%g", c.eso.tau) +
           " s wo " + fmt("%g", c.eso.wo) + " rad/s";
  return "ESO eqs. 22-24 beta " + fmt("%g", c.eso.beta1) + "/" + fmt("%g", c.eso.beta2) + "/" + fmt("%g", c.eso.beta3) +
         " delta " + fmt("%g", c.eso.delta) + " b0 " + fmt("%g", c.eso.b0);
}

std::string gainsText(const control::ControllerConfig& c) {
  return "kp " + fmt("%g", c.kp) + " V/mm, ki " + fmt("%g", c.ki) + " V/(mm s), kc " + fmt("%g", c.kc) + " V/mm" +
         (c.amc_bus_aware    ? " (eq. 17 through the commands on the bus)"
          : c.amc_as_printed ? " (eq. 17 as printed)"
                             : " (eq. 17 as increment)") +
         ", " + esoText(c) + ", delay " + std::to_string(c.delay_cycles) + " cycles";
}

// The plant in one line: its kind and, for a model plant, the effects that are on.
std::string plantText(const plant::PlantConfig& p) {
  if (p.kind == plant::PlantKind::Physics)
    return std::string("physics plant (mode ") + (p.physics.mode == physics::Mode::Rig ? "rig" : "reference") +
           "), sensor noise " + fmt("%g", p.physics.noise_std_mm) + " mm";
  if (p.kind == plant::PlantKind::External) return "external plant: " + p.external.name;
  const nlohmann::json j = p.toJson();
  std::string t = "model plant";
  for (const auto& [name, e] : j.at("effects").items()) {
    if (!e.value("enabled", false)) continue;
    t += ", " + name;
    for (const auto& [k, v] : e.items())
      if (k != "enabled" && v.is_number()) t += " " + k + " " + fmt("%g", v.get<double>());
  }
  return t + ", sensor noise " + fmt("%g", p.noise_std_mm) + " mm";
}

namespace {

const char* const kIdentNames[3] = {"u0", "u1", "u2"};

std::vector<Trajectory> identInputs() {
  return {identInput(), identInput(1.4), Trajectory::sine(0.05, kIdentAmplitude, 0.2)};
}

std::vector<Record> exciteOpenLoop(Context& x, const std::vector<Trajectory>& inputs) {
  x.log("table1: exciting the plant with u0, u1, u2 (open loop, " + fmt("%.0f", kIdentDuration) + " s each)");
  std::vector<Record> recs;
  for (size_t i = 0; i < inputs.size(); ++i)
    recs.push_back(recordOpenLoop(x.s.plant, inputs[i], kIdentDuration, x.dir + "ident_" + kIdentNames[i] + ".csv"));
  return recs;
}

void identify(Context& x) {
  if (!x.s.model_file.empty()) {
    x.ref = io::readModelFile(x.s.model_file);
    x.log("table1: using the model in " + x.s.model_file);
    x.json["model_file"] = x.s.model_file;
    return;
  }
  x.log("table1: identifying the Bouc-Wen model on u0 (GA + Nelder-Mead)");
  const auto fr = identifyOnRecord(x.dir + "ident_u0.csv", x.s.fit, x.s.log);
  x.ref = fr.model;
  io::writeModelFile(x.dir + "model.json", x.ref,
                     {{"data", "ident_u0.csv"},
                      {"rmse", fr.rmse},
                      {"generations", fr.generations},
                      {"evaluations", fr.evaluations},
                      {"seconds", fr.seconds}});
  x.log("table1: fitted in " + fmt("%.2f", fr.seconds) + " s, " + std::to_string(fr.generations) +
        " generations, RMSE " + fmt("%.4f", fr.rmse) + " mm -> " + x.dir + "model.json");
  x.json["fit"] = {{"rmse", fr.rmse}, {"generations", fr.generations}, {"seconds", fr.seconds}};
}

void printModel(Context& x) {
  const auto& c = x.ref.core();
  x.txt << "Identified reference model (alpha fixed at 1; see docs/MODEL.md):\n"
        << "  k = " << fmt("%.4f", c.k) << " mm/V, rho = " << fmt("%.4f", c.rho) << ", b = " << fmt("%.4f", c.b)
        << " mm, alpha = " << fmt("%.3f", c.alpha) << ", beta = " << fmt("%.4f", c.beta)
        << " 1/V, gamma = " << fmt("%.4f", c.gamma) << " 1/V\n"
        << "  (gain of u: k rho = " << fmt("%.4f", c.k * c.rho)
        << " mm/V; gain of h: k (1 - rho) = " << fmt("%.4f", c.k * (1 - c.rho)) << " mm/V)\n\n";
  x.json["model"] = io::modelToJson(x.ref);
}

void printTable1(Context& x, const ModelAccuracy (&acc)[3]) {
  x.txt
      << "Table 1. Modelling RMSE (mm) on the plant; paper's values in brackets.\n"
      << "                                   u0                 u1                 u2\n  Reference model             ";
  for (int i = 0; i < 3; ++i)
    x.txt << fmt("%8.3f", acc[i].reference_rmse) << " [" << fmt("%6.3f", PaperNumbers::table1_reference[i]) << "]";
  x.txt << "\n  Active model (posterior)    ";
  for (int i = 0; i < 3; ++i)
    x.txt << fmt("%8.1e", acc[i].posterior_rmse) << " [" << fmt("%6.1e", PaperNumbers::table1_active[i]) << "]";
  x.txt << "\n  Active model (1-step ahead) ";
  for (int i = 0; i < 3; ++i) x.txt << fmt("%8.1e", acc[i].one_step_rmse) << "          ";
  x.txt << "\n  Persistence y(k-1) baseline ";
  for (int i = 0; i < 3; ++i) x.txt << fmt("%8.1e", acc[i].persistence_rmse) << "          ";
  x.txt << "\n  (posterior: the filter has seen y(k); one-step-ahead: it has not - only this one says how\n"
           "   well the model predicts; persistence is the error of simply repeating the last sample.)\n\n";
}

}  // namespace

void useModel(Context& x) {
  identify(x);
  printModel(x);
}

void runTable1(Context& x) {
  const auto inputs = identInputs();
  const auto recs = exciteOpenLoop(x, inputs);
  identify(x);
  printModel(x);
  nlohmann::json t1 = nlohmann::json::object();
  ModelAccuracy acc[3];
  for (size_t i = 0; i < 3; ++i) {
    const auto& r = recs[i];
    std::vector<double> yr, yp;
    acc[i] = modelAccuracy(x.ref, x.s.ctrl.ukf, r.u, r.y, x.s.plant.Ts, &yr, &yp);
    const std::string base = x.dir + "table1_" + kIdentNames[i];
    io::writeCsvAtomic(base + ".csv", {"t", "u", "y", "y_reference", "y_active"}, {&r.t, &r.u, &r.y, &yr, &yp});
    t1[kIdentNames[i]] = {{"reference_rmse", acc[i].reference_rmse},
                          {"active_posterior_rmse", acc[i].posterior_rmse},
                          {"active_one_step_rmse", acc[i].one_step_rmse},
                          {"persistence_rmse", acc[i].persistence_rmse}};
    figureTable1(x, base + ".csv", base + ".png",
                 std::string("Model accuracy on ") + kIdentNames[i] + " = " + inputs[i].describe());
  }
  printTable1(x, acc);
  x.json["table1"] = t1;
}

void buildController(Context& x) {
  x.cc = controllerFor(x.s.ctrl, x.ref, x.s.plant);
  x.inv.build(x.ref, x.cc.u_min, x.cc.u_max, x.cc.Ts);
  const char* start = x.s.sine_start == SineStart::Trough ? "trough" : "centre";
  const control::GovernorLimits gov = control::mbcGovernor(x.cc);
  const model::Interval ff = control::mbcCommandRange(x.cc);
  const model::InverseFold fold = model::inverseFold(x.cc.model, ff.lo, ff.hi);
  const model::HeldRest rest = control::mbcModelRest(x.cc);
  x.json["readings"] = {
      {"ki", x.cc.ki},
      {"kp", x.cc.kp},
      {"kc", x.cc.kc},
      {"eso_form", x.cc.eso.order == 2 ? "paper (eqs. 22-24)" : "first-order (pamc's own)"},
      {"sine_start", start},
      {"plant", plantText(x.s.plant)},
      {"calibrated_on", x.s.calibrated_on},
      {"mbc_governor",
       {{"rate_mm_s", gov.rate_mm_s},
        {"accel_mm_s2", gov.accel_mm_s2},
        {"accel_carried_mm_s2", gov.accel_carried_mm_s2},
        {"lowered_to_the_models_pace", gov.from_model},
        {"models_pace", {{"speed_mm_s", gov.pace.speed}, {"accel_mm_s2", gov.pace.accel}}}}},
      {"models_inverse",
       {{"folds", fold.folds}, {"least_slope", fold.least}, {"at_input", fold.at_input}, {"gain", fold.gain}}},
      {"models_held_rest", {{"rests", rest.rests}, {"swing", rest.swing}, {"at_input", rest.at_command}}}};
  x.readings_line = gainsText(x.cc) + "\nplant: " + plantText(x.s.plant) + "; sines start at the " + start;
  x.txt << "Readings: " << gainsText(x.cc) << "\n  plant: " << plantText(x.s.plant) << "\n  sines start at the "
        << start << "\n  calibrated on: " << x.s.calibrated_on << "\n  MBC's setpoint governor: "
        << (gov.rate_mm_s > 0.0
                ? fmt("%.4g mm/s, ", gov.rate_mm_s) + fmt("%.4g mm/s^2", gov.accel_mm_s2) +
                      fmt(" (%.4g while the model carries the loop)", gov.accel_carried_mm_s2) +
                      (gov.from_model ? " (lowered to the model's pace)" : "") +
                      fmt("; the model's pace %.4g mm/s, ", gov.pace.speed) + fmt("%.4g mm/s^2", gov.pace.accel)
                : std::string("off"))
        << (fold.folds ? "\n  the model: " + model::describeInverseFold(fold) : std::string())
        << (rest.rests ? std::string()
                       : "\n  the model: " + model::describeHeldRest(rest) + ": the MBC is its PI alone")
        << "\n\n";
}

namespace {

bool wanted(const ExperimentSettings& s, const std::string& name) {
  return s.only.empty() || std::find(s.only.begin(), s.only.end(), name) != s.only.end();
}

void judge(Context& x) {
  const auto results = judgeClaims(x.json);
  const auto n = countClaims(results);
  x.txt << "The paper's claims, judged on this run (" << n.reproduced << " of " << n.predicted
        << " predictions reproduced; docs/EXPERIMENTS.md):\n"
        << formatClaims(results);
  x.json["claims"] = claimsJson(results);
  x.json["claims_count"] = {{"predicted", n.predicted},
                            {"reproduced", n.reproduced},
                            {"calibrated", n.calibrated},
                            {"calibrated_met", n.calibrated_held},
                            {"not_run", n.not_run}};
}

}  // namespace

}  // namespace detail

Trajectory identInput(double amplitude) { return Trajectory::sine(0.1, amplitude, 0.2); }

Record recordOpenLoop(const plant::PlantConfig& plant, const Trajectory& u, double duration_s, const std::string& csv) {
  plant::Plant p(plant);
  Record r = runOpenLoopInput(p, u, duration_s);
  if (!r.p.empty() && std::isfinite(r.p.front()))
    io::writeCsvAtomic(csv, {"t", "u", "y", "p"}, {&r.t, &r.u, &r.y, &r.p});
  else  // a plant without a pressure reading (kind external)
    io::writeCsvAtomic(csv, {"t", "u", "y"}, {&r.t, &r.u, &r.y});
  return r;
}

ident::FitResult identifyOnRecord(const std::string& csv, const ident::FitSettings& fit,
                                  const std::function<void(const std::string&)>& log) {
  const io::Measurement m = io::readMeasurementCsv(csv);
  int last_gen = 0;
  return ident::fit(model::Model{}, m, fit, [&](const char* stage, int it, double rmse) {
    if (log && std::string(stage) == "ga" && it - last_gen >= 25) {
      last_gen = it;
      log("  GA generation " + std::to_string(it) + ": RMSE " + io::fmt("%.4f", rmse) + " mm");
    }
  });
}

control::ControllerConfig controllerFor(const control::ControllerConfig& gains, const model::Model& m,
                                        const plant::PlantConfig& plant) {
  control::ControllerConfig cc = gains;
  cc.Ts = plant.Ts;
  cc.model = m;
  cc.u_min = plant.u_min;
  cc.u_max = plant.u_max;
  return cc;
}

Record runController(control::Kind kind, const control::ControllerConfig& cc, const control::InverseStatic& inv,
                     const plant::PlantConfig& plant, const ClosedLoopRun& run) {
  plant::Plant p(plant);
  auto ctrl = control::makeController(kind, cc);
  ClosedLoopRun rr = run;
  rr.delay_cycles = cc.delay_cycles;
  return runClosedLoop(*ctrl, p, rr, inv(run.home()));
}

ModelAccuracy modelAccuracy(const model::Model& m, const estimation::ActiveModelSettings& ukf,
                            const std::vector<double>& u, const std::vector<double>& y, double Ts,
                            std::vector<double>* y_ref, std::vector<double>* y_post) {
  ModelAccuracy a;
  const size_t n = u.size();
  std::vector<double> yr = m.simulate(u, Ts);
  estimation::ActiveModel am;
  am.configure(m, ukf, Ts);
  am.reset(u[0]);
  double sr = 0, sp = 0, so = 0, sn = 0;
  if (y_post) y_post->resize(n);
  for (size_t i = 0; i < n; ++i) {
    const auto st = am.update(u[i], y[i]);
    sr += (yr[i] - y[i]) * (yr[i] - y[i]);
    sp += (st.y_post - y[i]) * (st.y_post - y[i]);
    so += (st.y_prior - y[i]) * (st.y_prior - y[i]);
    const double prev = i ? y[i - 1] : y[0];
    sn += (prev - y[i]) * (prev - y[i]);
    if (y_post) (*y_post)[i] = st.y_post;
  }
  const double N = static_cast<double>(n);
  a.reference_rmse = std::sqrt(sr / N);
  a.posterior_rmse = std::sqrt(sp / N);
  a.one_step_rmse = std::sqrt(so / N);
  a.persistence_rmse = std::sqrt(sn / N);
  if (y_ref) *y_ref = std::move(yr);
  return a;
}

ExperimentReport runExperiments(const ExperimentSettings& s) {
  for (const auto& o : s.only)
    if (o != "table1" && o != "table2" && o != "triangle" && o != "discontinuous" && o != "payload")
      throw std::invalid_argument("--only: unknown experiment '" + o +
                                  "' (known: table1, table2, triangle, discontinuous, payload)");
  io::makeDirectory(s.out_dir);
  detail::Context x(s);
  x.dir = s.out_dir + "/";
  x.figures = s.figures && report::haveGnuplot();
  if (s.figures && !x.figures) x.warn("gnuplot not found (apt-get install gnuplot-nox); figures skipped");
  if (s.table1 || s.model_file.empty())
    detail::runTable1(x);
  else
    detail::useModel(x);
  detail::buildController(x);
  if (detail::wanted(s, "table2"))
    detail::runTable2(x);
  else if (detail::wanted(s, "triangle"))
    detail::runTriangle(x);
  if (detail::wanted(s, "discontinuous")) detail::runDiscontinuous(x);
  if (detail::wanted(s, "payload")) detail::runPayload(x);
  detail::judge(x);
  ExperimentReport rep;
  rep.json = std::move(x.json);
  rep.text = x.txt.str();
  io::writeFileAtomic(x.dir + "summary.txt", rep.text);
  io::writeFileAtomic(x.dir + "summary.json", rep.json.dump(2) + "\n");
  return rep;
}

}  // namespace pamc::sim
