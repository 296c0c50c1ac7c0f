#include "tools/plot.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <map>

namespace facemorph::tools {

namespace {

// 5x7 glyphs, one byte per row, bit 4 leftmost. Capitals are drawn as small letters.
const std::map<char, std::array<uint8_t, 7>>& glyphs() {
  static const std::map<char, std::array<uint8_t, 7>> table = {
      {'0', {0x0e, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0e}}, {'1', {0x04, 0x0c, 0x04, 0x04, 0x04, 0x04, 0x0e}},
      {'2', {0x0e, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1f}}, {'3', {0x1e, 0x01, 0x01, 0x0e, 0x01, 0x01, 0x1e}},
      {'4', {0x02, 0x06, 0x0a, 0x12, 0x1f, 0x02, 0x02}}, {'5', {0x1f, 0x10, 0x1e, 0x01, 0x01, 0x11, 0x0e}},
      {'6', {0x06, 0x08, 0x10, 0x1e, 0x11, 0x11, 0x0e}}, {'7', {0x1f, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08}},
      {'8', {0x0e, 0x11, 0x11, 0x0e, 0x11, 0x11, 0x0e}}, {'9', {0x0e, 0x11, 0x11, 0x0f, 0x01, 0x02, 0x0c}},
      {'.', {0x00, 0x00, 0x00, 0x00, 0x00, 0x0c, 0x0c}}, {'%', {0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03}},
      {'-', {0x00, 0x00, 0x00, 0x1f, 0x00, 0x00, 0x00}}, {'/', {0x01, 0x01, 0x02, 0x04, 0x08, 0x10, 0x10}},
      {'(', {0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02}}, {')', {0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08}},
      {':', {0x00, 0x0c, 0x0c, 0x00, 0x0c, 0x0c, 0x00}}, {'=', {0x00, 0x00, 0x1f, 0x00, 0x1f, 0x00, 0x00}},
      {'+', {0x00, 0x04, 0x04, 0x1f, 0x04, 0x04, 0x00}}, {' ', {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00}},
      {'a', {0x00, 0x00, 0x0e, 0x01, 0x0f, 0x11, 0x0f}}, {'b', {0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x1e}},
      {'c', {0x00, 0x00, 0x0e, 0x10, 0x10, 0x11, 0x0e}}, {'d', {0x01, 0x01, 0x0d, 0x13, 0x11, 0x11, 0x0f}},
      {'e', {0x00, 0x00, 0x0e, 0x11, 0x1f, 0x10, 0x0e}}, {'f', {0x06, 0x09, 0x08, 0x1c, 0x08, 0x08, 0x08}},
      {'g', {0x00, 0x0f, 0x11, 0x11, 0x0f, 0x01, 0x0e}}, {'h', {0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x11}},
      {'i', {0x04, 0x00, 0x0c, 0x04, 0x04, 0x04, 0x0e}}, {'j', {0x02, 0x00, 0x06, 0x02, 0x02, 0x12, 0x0c}},
      {'k', {0x10, 0x10, 0x12, 0x14, 0x18, 0x14, 0x12}}, {'l', {0x0c, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0e}},
      {'m', {0x00, 0x00, 0x1a, 0x15, 0x15, 0x11, 0x11}}, {'n', {0x00, 0x00, 0x16, 0x19, 0x11, 0x11, 0x11}},
      {'o', {0x00, 0x00, 0x0e, 0x11, 0x11, 0x11, 0x0e}}, {'p', {0x00, 0x00, 0x1e, 0x11, 0x1e, 0x10, 0x10}},
      {'q', {0x00, 0x00, 0x0d, 0x13, 0x0f, 0x01, 0x01}}, {'r', {0x00, 0x00, 0x16, 0x19, 0x10, 0x10, 0x10}},
      {'s', {0x00, 0x00, 0x0e, 0x10, 0x0e, 0x01, 0x1e}}, {'t', {0x08, 0x08, 0x1c, 0x08, 0x08, 0x09, 0x06}},
      {'u', {0x00, 0x00, 0x11, 0x11, 0x11, 0x13, 0x0d}}, {'v', {0x00, 0x00, 0x11, 0x11, 0x11, 0x0a, 0x04}},
      {'w', {0x00, 0x00, 0x11, 0x11, 0x15, 0x15, 0x0a}}, {'x', {0x00, 0x00, 0x11, 0x0a, 0x04, 0x0a, 0x11}},
      {'y', {0x00, 0x00, 0x11, 0x11, 0x0f, 0x01, 0x0e}}, {'z', {0x00, 0x00, 0x1f, 0x02, 0x04, 0x08, 0x1f}},
  };
  return table;
}

class Canvas {
 public:
  explicit Canvas(Image& image) : image_(image) {}
  void pixel(int x, int y, std::array<uint8_t, 3> c) {
    if (x < 0 || y < 0 || x >= image_.width || y >= image_.height) return;
    std::copy(c.begin(), c.end(), image_.at(x, y));
  }
  void line(double x0, double y0, double x1, double y1, std::array<uint8_t, 3> c) {
    const int steps = static_cast<int>(std::max(std::abs(x1 - x0), std::abs(y1 - y0))) + 1;
    for (int s = 0; s <= steps; ++s) {
      const double t = static_cast<double>(s) / steps;
      pixel(static_cast<int>(std::lround(x0 + t * (x1 - x0))), static_cast<int>(std::lround(y0 + t * (y1 - y0))), c);
    }
  }
  void text(int x, int y, const std::string& s, std::array<uint8_t, 3> c = {0, 0, 0}) {
    for (char ch : s) {
      const auto it = glyphs().find(static_cast<char>(std::tolower(static_cast<unsigned char>(ch))));
      if (it != glyphs().end()) {
        for (int row = 0; row < 7; ++row) {
          for (int col = 0; col < 5; ++col) {
            if (it->second[static_cast<size_t>(row)] & (0x10 >> col)) pixel(x + col, y + row, c);
          }
        }
      }
      x += 6;
    }
  }
  void vertical_text(int x, int y, const std::string& s, std::array<uint8_t, 3> c = {0, 0, 0}) {
    // Rotated a quarter turn counter-clockwise, read from the bottom up.
    for (char ch : s) {
      const auto it = glyphs().find(static_cast<char>(std::tolower(static_cast<unsigned char>(ch))));
      if (it != glyphs().end()) {
        for (int row = 0; row < 7; ++row) {
          for (int col = 0; col < 5; ++col) {
            if (it->second[static_cast<size_t>(row)] & (0x10 >> col)) pixel(x + row, y - col, c);
          }
        }
      }
      y -= 6;
    }
  }

 private:
  Image& image_;
};

// About five round tick values covering [lo, hi].
std::vector<double> ticks(double lo, double hi) {
  const double span = hi - lo;
  if (!(span > 0)) return {lo};
  const double raw = span / 5, magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  double step = magnitude;
  for (double m : {1.0, 2.0, 2.5, 5.0, 10.0}) {
    if (m * magnitude >= raw) {
      step = m * magnitude;
      break;
    }
  }
  std::vector<double> out;
  for (double v = std::ceil(lo / step - 1e-9) * step; v <= hi + 1e-9 * span; v += step) out.push_back(std::abs(v) < 1e-12 * step ? 0.0 : v);
  return out;
}

std::string number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}

}  // namespace

Image line_plot(const std::vector<PlotSeries>& series, const PlotOptions& options) {
  Image image(options.width, options.height, 3);
  std::fill(image.pixels.begin(), image.pixels.end(), uint8_t{255});
  Canvas canvas(image);
  double x_lo = 1e300, x_hi = -1e300, y_lo = 1e300, y_hi = -1e300;
  for (const PlotSeries& s : series) {
    for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      x_lo = std::min(x_lo, s.x[i]), x_hi = std::max(x_hi, s.x[i]);
      y_lo = std::min(y_lo, s.y[i]), y_hi = std::max(y_hi, s.y[i]);
    }
  }
  if (x_lo > x_hi) x_lo = 0, x_hi = 1, y_lo = 0, y_hi = 1;
  if (options.y_from_zero) y_lo = std::min(y_lo, 0.0);
  if (x_hi <= x_lo) x_hi = x_lo + 1;
  if (y_hi <= y_lo) y_hi = y_lo + 1;
  y_hi += 0.05 * (y_hi - y_lo);
  const int left = 70, right = options.width - 20, top = 20, bottom = options.height - 45;
  auto px = [&](double x) { return left + (x - x_lo) / (x_hi - x_lo) * (right - left); };
  auto py = [&](double y) { return bottom - (y - y_lo) / (y_hi - y_lo) * (bottom - top); };
  const std::array<uint8_t, 3> grey = {225, 225, 225}, mark = {235, 150, 60};
  for (double x : options.vertical_marks) canvas.line(px(x), top, px(x), bottom, mark);
  for (double t : ticks(y_lo, y_hi)) {
    canvas.line(left, py(t), right, py(t), grey);
    const std::string label = number(t);
    canvas.text(left - 8 - 6 * static_cast<int>(label.size()), static_cast<int>(py(t)) - 3, label);
  }
  for (double t : ticks(x_lo, x_hi)) {
    canvas.line(px(t), bottom, px(t), bottom + 4, {0, 0, 0});
    const std::string label = number(t);
    canvas.text(static_cast<int>(px(t)) - 3 * static_cast<int>(label.size()), bottom + 9, label);
  }
  canvas.line(left, top, left, bottom, {0, 0, 0});
  canvas.line(left, bottom, right, bottom, {0, 0, 0});
  canvas.text((left + right) / 2 - 3 * static_cast<int>(options.x_label.size()), options.height - 14, options.x_label);
  canvas.vertical_text(12, (top + bottom) / 2 + 3 * static_cast<int>(options.y_label.size()), options.y_label);
  for (const PlotSeries& s : series) {
    for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (!std::isfinite(s.y[i])) continue;
      if (s.line && i > 0 && std::isfinite(s.y[i - 1])) canvas.line(px(s.x[i - 1]), py(s.y[i - 1]), px(s.x[i]), py(s.y[i]), s.color);
      if (s.markers) {
        for (int dy = -2; dy <= 2; ++dy) {
          for (int dx = -2; dx <= 2; ++dx)
            canvas.pixel(static_cast<int>(std::lround(px(s.x[i]))) + dx, static_cast<int>(std::lround(py(s.y[i]))) + dy, s.color);
        }
      }
    }
  }
  // The legend: one line per labelled series, in its colour, at the top right.
  int legend_y = top + 6;
  for (const PlotSeries& s : series) {
    if (s.label.empty()) continue;
    const int x = right - 6 * static_cast<int>(s.label.size()) - 24;
    for (int dy = -1; dy <= 1; ++dy) canvas.line(x, legend_y + 3 + dy, x + 14, legend_y + 3 + dy, s.color);
    canvas.text(x + 20, legend_y, s.label, s.color);
    legend_y += 12;
  }
  return image;
}

}  // namespace facemorph::tools
