// pamc_oracle_sim: writes a measurement record (CSV t,u,y[,load]) made by the test oracle, either a
// record of a pre-decided case (tests/oracle/cases.json) or a custom one. See tests/oracle/README.md.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "oracle_sim.hpp"

using namespace pamc::oracle;

namespace {

std::string effectsText(const std::vector<EffectSpec>& effects) {
  std::ostringstream os;
  for (size_t i = 0; i < effects.size(); ++i) {
    os << (i ? " " : "") << effects[i].name;
    const char* sep = ":";
    for (const auto& [k, v] : effects[i].params) {
      os << sep << k << "=" << v;
      sep = ",";
    }
  }
  return effects.empty() ? "none" : os.str();
}

int run(int argc, char** argv) {
  CLI::App app{
      "pamc_oracle_sim: the test oracle, an independent continuous-time PAM simulator (Bouc-Wen core and "
      "physical effects, own adaptive RK45); writes a measurement CSV t,u,y[,load] (s, V, mm)"};
  app.set_help_flag("-h,--help", "Print this help and exit");
  std::string cases_path = defaultCasesPath(), case_name, which = "train", out, core_text, input = "mixed", load_spec;
  std::vector<std::string> effect_texts;
  bool list = false, list_effects = false;
  double duration = 60.0, noise = 0.005, quantum = 0.001, valve_tau = 1e-6, rtol = 1e-11;
  std::uint64_t seed = 1;
  app.add_flag("--list", list, "List the cases of the cases file with their expected effects");
  app.add_flag("--effects", list_effects, "List the effects with their parameters, defaults and bounds");
  app.add_option("--cases", cases_path, "Cases file (default: the source tree's tests/oracle/cases.json)");
  app.add_option("--case", case_name, "Write a record of this case");
  app.add_option("--record", which, "Which record of the case: train or validate")
      ->check(CLI::IsMember({"train", "validate"}));
  app.add_option("--out", out, "Output CSV (written to FILE.tmp, then renamed)");
  app.add_option("--core", core_text,
                 "Custom record: core parameters k=..,rho=..,b=..,alpha=..,beta=..,gamma=.. "
                 "(default k=6.5,rho=1.15,b=20,alpha=1,beta=0.5,gamma=0.2)");
  app.add_option("--effect", effect_texts, "Custom record: an effect NAME[:param=v,param=v] (repeatable)");
  app.add_option("--input", input,
                 "Custom record: excitation SPEC, segments KIND[:key=v,...] joined by '+': steps, chirp, sine, "
                 "triangle, multisine, hold, ramp, mixed (dur=S fixes a segment's length)")
      ->capture_default_str();
  app.add_option("--load", load_spec, "Custom record: load column SPEC (same syntax as --input, in load units)");
  app.add_option("--duration", duration, "Custom record: length [s]")->capture_default_str();
  app.add_option("--noise", noise, "Custom record: Gaussian noise std [mm]")->capture_default_str();
  app.add_option("--quantum", quantum, "Quantisation step of y [mm] (0: none)")->capture_default_str();
  app.add_option("--seed", seed, "Custom record: seed of the excitation and the noise")->capture_default_str();
  app.add_option("--valve-tau", valve_tau, "Time constant of the valve stage [s]")->capture_default_str();
  app.add_option("--rtol", rtol, "Integrator tolerance (relative and absolute)")->capture_default_str();

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp&) {
    std::cout << app.help();
    return 0;
  } catch (const CLI::ParseError& e) {
    std::cerr << "pamc_oracle_sim: " << e.what() << "\n";
    return 2;
  }

  try {
    if (list_effects) {
      for (const auto& e : effectTable()) {
        std::cout << e.name << (e.needs_load ? " (needs a load column)" : "") << ": " << e.meaning << "\n";
        for (const auto& p : e.params)
          std::cout << "    " << p.name << " default " << p.def << " in [" << p.lo << ", " << p.hi << "]\n";
      }
      return 0;
    }
    if (list) {
      for (const auto& c : loadCases(cases_path)) {
        std::cout << c.name << "  expected [";
        for (size_t i = 0; i < c.expected.size(); ++i) std::cout << (i ? ", " : "") << c.expected[i];
        std::cout << "]  train " << c.train.input << " " << c.train.duration << " s, validate " << c.validate.input
                  << " " << c.validate.duration << " s\n";
      }
      return 0;
    }
    if (out.empty()) throw std::invalid_argument("--out FILE.csv is required");
    SimOptions opt;
    opt.valve_tau = valve_tau;
    opt.rtol = opt.atol = rtol;
    opt.quantum = quantum;
    if (!(valve_tau > 0 && valve_tau <= 0.01)) throw std::invalid_argument("--valve-tau must be in (0, 0.01]");
    if (!(rtol >= 1e-14 && rtol <= 1e-3)) throw std::invalid_argument("--rtol must be in [1e-14, 1e-3]");
    if (!(quantum >= 0 && quantum <= 1)) throw std::invalid_argument("--quantum must be in [0, 1]");
    Record r;
    std::string what;
    const auto t0 = std::chrono::steady_clock::now();
    if (!case_name.empty()) {
      for (const char* o : {"--core", "--effect", "--input", "--load", "--duration", "--noise", "--seed"})
        if (app.count(o)) throw std::invalid_argument(std::string(o) + " does not go with --case");
      const Case* c = nullptr;
      const auto cases = loadCases(cases_path);
      for (const auto& k : cases)
        if (k.name == case_name) c = &k;
      if (!c) throw std::invalid_argument("no case '" + case_name + "' in " + cases_path + " (see --list)");
      r = makeCaseRecord(*c, which, opt);
      what = "case " + c->name + " " + which + ", effects " + effectsText(c->effects);
    } else {
      if (app.count("--record")) throw std::invalid_argument("--record goes with --case");
      if (!(duration > 0 && duration <= 100000)) throw std::invalid_argument("--duration must be in (0, 100000] s");
      if (!(noise >= 0 && noise <= 100)) throw std::invalid_argument("--noise must be in [0, 100]");
      const Core core = parseCore(core_text);
      std::vector<EffectSpec> effects;
      for (const auto& t : effect_texts) effects.push_back(parseEffect(t));
      validateEffects(effects);
      const std::vector<double> u = makeSignal(input, duration, opt.Ts, seed);
      std::vector<double> load;
      if (!load_spec.empty()) load = makeSignal(load_spec, duration, opt.Ts, seed ^ 0x5bd1e995ULL);
      opt.noise_std = noise;
      opt.noise_seed = seed * 0x9E3779B97F4A7C15ULL + 0x632BE59BD9B4E019ULL;
      r = simulate(core, effects, u, load.empty() ? nullptr : &load, opt);
      what = "custom, effects " + effectsText(effects);
    }
    writeRecordCsv(out, r);
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("wrote %s: %zu samples (%.3f s), %s; noise %.6g mm (std %.6g, quantum %.6g); %ld steps, %.2f s\n",
                out.c_str(), r.t.size(), static_cast<double>(r.t.size()) * r.Ts, what.c_str(), r.noise(), r.noise_std,
                r.quantum, r.steps, secs);
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "pamc_oracle_sim: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace

int main(int argc, char** argv) { return run(argc, argv); }
