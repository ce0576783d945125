#include "nnoe_fast.hpp"

#include <algorithm>

#include "mlp.hpp"

namespace gcpipe::calibrate {

std::vector<double> nnoe_simulate_float(const NnoeModel& m, const Channels& u, std::size_t end) {
  const neural::MlpSingle net(m.net);
  const int na = m.structure.na;
  std::size_t lag = static_cast<std::size_t>(na);
  for (std::size_t c = 0; c < u.size(); ++c) lag = std::max(lag, static_cast<std::size_t>(m.structure.lags(c)));
  // The inputs normalised once (off the recurrence's critical path).
  std::vector<std::vector<float>> un(u.size(), std::vector<float>(end));
  for (std::size_t c = 0; c < u.size(); ++c)
    for (std::size_t t = 0; t < end; ++t) un[c][t] = static_cast<float>((u[c][t] - m.u_offset[c]) / m.u_scale[c]);
  std::vector<float> yn(end, 0.0f);  // normalised outputs; 0 = the output's centre
  std::vector<float> x(static_cast<std::size_t>(net.input_size()));
  for (std::size_t t = lag; t < end; ++t) {
    std::size_t j = 0;
    for (int i = 1; i <= na; ++i) x[j++] = yn[t - static_cast<std::size_t>(i)];
    for (std::size_t c = 0; c < u.size(); ++c)
      for (int i = 1; i <= m.structure.lags(c); ++i) x[j++] = un[c][t - static_cast<std::size_t>(i)];
    yn[t] = std::clamp(net(x.data()), -20.0f, 20.0f);
  }
  std::vector<double> y(end);
  for (std::size_t t = 0; t < end; ++t) y[t] = static_cast<double>(yn[t]) * m.y_scale + m.y_offset;
  return y;
}

}  // namespace gcpipe::calibrate
