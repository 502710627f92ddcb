#include "diagnose/spectrum.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <stdexcept>

#include <unsupported/Eigen/FFT>

#include "io/measurement.hpp"
#include "io/text.hpp"
#include "report/figures.hpp"

namespace pamc::diagnose {

namespace {

using io::fmt;
using cvec = std::vector<std::complex<double>>;

constexpr size_t kMaxSegment = 4096;
constexpr double kLineFactor = 10.0;  // a line stands this far above the running median
constexpr int kMedianHalfWidth = 24;  // bins each side of the running median
constexpr double kMinLineHz = 0.5;    // below this a "line" is the excitation's own slow content
constexpr size_t kMaxPeaks = 5;
constexpr int kLineBins = 2;  // bins each side summed into a line's power (Hann's main lobe)

size_t segmentLength(size_t n) {
  size_t len = 256;
  while (len * 2 <= std::min(kMaxSegment, n / 4)) len *= 2;
  return len;
}

// Accumulated Welch sums: |E|^2, |U|^2 and E conj(U) per bin, and the window's power.
struct WelchSums {
  std::vector<double> ee, uu;
  cvec eu;
  double wpow = 0;
  int segments = 0;
};

WelchSums welch(const std::vector<double>& e, const std::vector<double>& u, size_t len) {
  WelchSums w;
  const size_t bins = len / 2 + 1;
  w.ee.assign(bins, 0.0);
  w.uu.assign(bins, 0.0);
  w.eu.assign(bins, {0.0, 0.0});
  std::vector<double> win(len), se(len), su(len);
  for (size_t i = 0; i < len; ++i) {
    win[i] = 0.5 - 0.5 * std::cos(2 * M_PI * static_cast<double>(i) / static_cast<double>(len));
    w.wpow += win[i] * win[i];
  }
  Eigen::FFT<double> fft;
  cvec E, U;
  for (size_t start = 0; start + len <= e.size(); start += len / 2) {
    double me = 0, mu = 0;
    for (size_t i = 0; i < len; ++i) me += e[start + i], mu += u[start + i];
    me /= static_cast<double>(len);
    mu /= static_cast<double>(len);
    for (size_t i = 0; i < len; ++i) se[i] = (e[start + i] - me) * win[i], su[i] = (u[start + i] - mu) * win[i];
    fft.fwd(E, se);
    fft.fwd(U, su);
    for (size_t k = 0; k < bins; ++k) {
      w.ee[k] += std::norm(E[k]);
      w.uu[k] += std::norm(U[k]);
      w.eu[k] += E[k] * std::conj(U[k]);
    }
    ++w.segments;
  }
  return w;
}

std::vector<double> runningMedian(const std::vector<double>& v) {
  std::vector<double> out(v.size()), buf;
  for (size_t k = 0; k < v.size(); ++k) {
    const size_t lo = k > static_cast<size_t>(kMedianHalfWidth) ? k - kMedianHalfWidth : 0;
    const size_t hi = std::min(v.size(), k + kMedianHalfWidth + 1);
    buf.assign(v.begin() + static_cast<long>(lo), v.begin() + static_cast<long>(hi));
    std::nth_element(buf.begin(), buf.begin() + static_cast<long>(buf.size() / 2), buf.end());
    out[k] = buf[buf.size() / 2];
  }
  return out;
}

void findPeaks(ResidualSpectrum& s) {
  const auto base = runningMedian(s.psd);
  for (size_t k = 1; k + 1 < s.psd.size(); ++k) {
    if (s.hz[k] < kMinLineHz || s.psd[k] < s.psd[k - 1] || s.psd[k] < s.psd[k + 1]) continue;
    if (s.psd[k] < kLineFactor * base[k] || (s.noise_psd > 0 && s.psd[k] < kLineFactor * s.noise_psd)) continue;
    double power = 0;
    const size_t lo = k >= static_cast<size_t>(kLineBins) ? k - kLineBins : 0,
                 hi = std::min(s.psd.size() - 1, k + kLineBins);
    for (size_t j = lo; j <= hi; ++j) power += (s.psd[j] - base[j]) * s.df;
    // Hann's equivalent noise bandwidth is 1.5 bins: the sum over the main lobe holds the line's power.
    // The line's frequency between bins: a parabola through the log-psd of the peak and its neighbours.
    const double a = std::log(s.psd[k - 1]), b = std::log(s.psd[k]), c = std::log(s.psd[k + 1]);
    const double den = a - 2 * b + c;
    const double shift = den < 0 ? std::clamp(0.5 * (a - c) / den, -0.5, 0.5) : 0.0;
    SpectrumPeak p{s.hz[k] + shift * s.df, std::sqrt(2.0 * std::max(power, 0.0)), s.coherence[k], false};
    p.coherent = p.coherence >= s.coherence_threshold;
    s.peaks.push_back(p);
  }
  std::sort(s.peaks.begin(), s.peaks.end(),
            [](const SpectrumPeak& a, const SpectrumPeak& b) { return a.amplitude > b.amplitude; });
  if (s.peaks.size() > kMaxPeaks) s.peaks.resize(kMaxPeaks);
}

double medianAbove(const ResidualSpectrum& s, double hz) {
  std::vector<double> v;
  for (size_t k = 0; k < s.psd.size(); ++k)
    if (s.hz[k] >= hz) v.push_back(s.psd[k]);
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// Where the power lies: the rms, the frequency below which 90 % of it is, and how coherent with the
// input the residual is in that band.
void powerBand(ResidualSpectrum& s) {
  double total = 0;
  for (size_t k = 1; k < s.psd.size(); ++k) total += s.psd[k] * s.df;
  s.rms = std::sqrt(total);
  double acc = 0, coh = 0, w = 0;
  for (size_t k = 1; k < s.psd.size(); ++k) {
    acc += s.psd[k] * s.df;
    coh += s.psd[k] * s.coherence[k];
    w += s.psd[k];
    if (acc >= 0.9 * total) {
      s.f90_hz = s.hz[k];
      break;
    }
  }
  s.band_coherence = w > 0 ? coh / w : 0.0;
}

}  // namespace

ResidualSpectrum residualSpectrum(const std::vector<double>& e, const std::vector<double>& u, double Ts,
                                  double noise_std) {
  if (e.size() != u.size()) throw std::invalid_argument("residual spectrum: residual and input differ in length");
  ResidualSpectrum s;
  if (!(Ts > 0) || e.size() < 1024) return s;
  const size_t len = segmentLength(e.size());
  const auto w = welch(e, u, len);
  s.fs = 1.0 / Ts;
  s.df = s.fs / static_cast<double>(len);
  s.segments = w.segments;
  const double scale = 1.0 / (s.fs * w.wpow * w.segments);
  for (size_t k = 0; k < w.ee.size(); ++k) {
    const double one_sided = (k == 0 || k == len / 2) ? 1.0 : 2.0;
    s.hz.push_back(static_cast<double>(k) * s.df);
    s.psd.push_back(one_sided * w.ee[k] * scale);
    const double den = w.ee[k] * w.uu[k];
    s.coherence.push_back(den > 0 ? std::norm(w.eu[k]) / den : 0.0);
  }
  s.noise_psd = noise_std > 0 ? 2.0 * noise_std * noise_std / s.fs : 0.0;
  s.floor_psd = medianAbove(s, 1.0);
  s.coherence_threshold = std::max(0.5, w.segments > 1 ? 1.0 - std::pow(0.05, 1.0 / (w.segments - 1)) : 1.0);
  findPeaks(s);
  powerBand(s);
  s.white = s.peaks.empty() && noise_std > 0 && s.rms < 2.0 * noise_std && s.f90_hz > 0.5 * s.fs / 2;
  return s;
}

nlohmann::json toJson(const ResidualSpectrum& s) {
  nlohmann::json peaks = nlohmann::json::array();
  for (const auto& p : s.peaks)
    peaks.push_back({{"hz", p.hz}, {"amplitude", p.amplitude}, {"coherence", p.coherence}, {"coherent", p.coherent}});
  return {{"peaks", peaks},
          {"df_hz", s.df},
          {"segments", s.segments},
          {"floor_psd", s.floor_psd},
          {"noise_psd", s.noise_psd},
          {"coherence_threshold", s.coherence_threshold},
          {"white", s.white},
          {"rms", s.rms},
          {"f90_hz", s.f90_hz},
          {"band_coherence", s.band_coherence},
          {"summary", describeSpectrum(s)}};
}

std::string describeSpectrum(const ResidualSpectrum& s) {
  if (s.segments == 0) return "too short for a spectrum";
  if (s.white) return "its spectrum is flat at the sensor noise's level with no line: white, at the noise";
  std::string t;
  if (!s.peaks.empty()) {
    const auto& p = s.peaks.front();
    t = "its spectrum has a line at " + fmt("%.2f", p.hz) + " Hz (amplitude " + fmt("%.3g", p.amplitude) +
        ", coherence " + fmt("%.2f", p.coherence) + " with the input: " +
        (p.coherent ? "driven by the input - a dynamic the model lacks)"
                    : "not driven by the input - a disturbance from elsewhere)");
    if (s.peaks.size() > 1) t += " and " + std::to_string(s.peaks.size() - 1) + " weaker line(s)";
  } else {
    t = "its spectrum has no line";
  }
  if (s.noise_psd > 0 && s.rms < 2.0 * std::sqrt(0.5 * s.noise_psd * s.fs)) return t;
  const std::string band = s.f90_hz < 0.25 * s.fs / 2 ? "90 % of its power lies below " + fmt("%.3g", s.f90_hz) + " Hz"
                                                      : "its power is spread over the whole band";
  return t + "; " + band + " with a coherence of " + fmt("%.2f", s.band_coherence) + " with the input there (" +
         (s.band_coherence >= 0.5
              ? "linearly driven by the input: dynamics the model lacks"
              : "not linearly related to the input: a nonlinear effect of it, a drift or a disturbance") +
         "), not white noise";
}

void writeSpectrumReport(const ResidualSpectrum& s, const std::string& dir, const std::string& title,
                         std::vector<std::string>* warnings) {
  if (s.segments == 0) return;
  const std::vector<double> noise(s.hz.size(), s.noise_psd), thr(s.hz.size(), s.coherence_threshold);
  const std::string csv = dir + "spectrum.csv";
  io::writeCsvAtomic(csv, {"hz", "psd", "noise_psd", "coherence", "coherence_threshold"},
                     {&s.hz, &s.psd, &noise, &s.coherence, &thr});
  if (!report::haveGnuplot()) return;
  report::Panel psd{"residual power spectral density (Welch, " + std::to_string(s.segments) + " segments)",
                    "f [Hz]",
                    "PSD [y-unit^2/Hz]",
                    {{csv, "hz", "psd", "residual"}}};
  if (s.noise_psd > 0) psd.series.push_back({csv, "hz", "noise_psd", "sensor noise level", "lines dt 2", "#000000"});
  psd.log_y = psd.log_x = true;
  psd.every = 1;
  report::Panel coh{"coherence of the residual with the input",
                    "f [Hz]",
                    "coherence",
                    {{csv, "hz", "coherence", "coherence"},
                     {csv, "hz", "coherence_threshold", "threshold", "lines dt 2", "#000000"}}};
  coh.log_x = true;
  coh.every = 1;
  std::string err;
  if (!report::renderFigure(dir + "spectrum.png", title + "\n" + describeSpectrum(s), {psd, coh}, err) && warnings)
    warnings->push_back(err);
}

}  // namespace pamc::diagnose
