// The residual in frequency: its Welch spectrum and its coherence with the input. A line in the
// spectrum that is coherent with the input is a dynamic the model lacks (the input drives it); one that
// is not is a disturbance from elsewhere (a pump, a fan, the mains). A residual without lines whose level
// is the sensor noise's is white and at the noise.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace pamc::diagnose {

struct SpectrumPeak {
  double hz = 0;
  double amplitude = 0;   // of the sinusoid that carries the line's power (y units)
  double coherence = 0;   // magnitude-squared coherence with the input at the line, 0..1
  bool coherent = false;  // above the coherence threshold
};

struct ResidualSpectrum {
  double fs = 0, df = 0;
  int segments = 0;                        // Welch segments averaged
  std::vector<double> hz, psd, coherence;  // one-sided, bins 0..N/2 (psd in y-units^2/Hz)
  std::vector<SpectrumPeak> peaks;         // strongest first
  double floor_psd = 0;                    // median of the psd above 1 Hz
  double noise_psd = 0;                    // the sensor noise's flat level (2 sigma^2 / fs); 0 when unknown
  double coherence_threshold = 0;          // 95 % level of zero coherence for `segments`, at least 0.5
  double rms = 0;                          // of the residual without its mean (from the psd)
  double f90_hz = 0;                       // 90 % of the residual's power lies below this frequency
  double band_coherence = 0;               // coherence with the input over [0, f90], weighted by the psd
  bool white = false;                      // no line, and its rms within 2x the noise's and spread like it
};

// Welch (Hann, 50 % overlap, segments of up to 4096 samples) of e and of u, their coherence, and the
// lines: local maxima at least kLineFactor above the running median of the psd. noise_std: the sensor
// noise (rms), 0 when unknown. Throws std::invalid_argument when the records differ in length.
ResidualSpectrum residualSpectrum(const std::vector<double>& e, const std::vector<double>& u, double Ts,
                                  double noise_std);

nlohmann::json toJson(const ResidualSpectrum& s);
// One sentence on what the spectrum shows ("white and at the noise", "a line at 11.3 Hz ...").
std::string describeSpectrum(const ResidualSpectrum& s);

// spectrum.csv (hz, psd, noise_psd, coherence, coherence_threshold) and spectrum.png into the folder
// `dir` (with its trailing '/'); a failed figure is a warning.
void writeSpectrumReport(const ResidualSpectrum& s, const std::string& dir, const std::string& title,
                         std::vector<std::string>* warnings);

}  // namespace pamc::diagnose
