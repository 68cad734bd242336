// A downstream program built against the installed hgdeform: the harmonic field of a bar.
#include <hgdeform/geometry.h>
#include <hgdeform/harmonic_field.h>
#include <hgdeform/shapes.h>

#include <algorithm>
#include <cstdio>
#include <vector>

int main() {
  const hgd::Shape shape = hgd::shapes::bar(1.0f, 0.1f, 0.02f);
  const hgd::Geometry geometry = hgd::extractGeometry(shape);
  std::vector<std::vector<int>> fixed(1);
  std::vector<int> manipulated;
  for (std::size_t i = 0; i < geometry.size(); ++i) {
    const double x = geometry.world(i).x();
    if (x < 0.05) fixed[0].push_back(static_cast<int>(i));
    if (x > 0.95) manipulated.push_back(static_cast<int>(i));
  }
  hgd::HarmonicField field;
  field.setInputCloud(geometry.points);
  field.setHandles(fixed, manipulated);
  std::vector<float> phi;
  field.compute(phi);
  std::printf("consumer: %zu points\n", geometry.size());
  if (phi.size() != geometry.size() || phi.empty()) return 1;
  const auto [lo, hi] = std::minmax_element(phi.begin(), phi.end());
  std::printf("consumer: phi in [%g, %g]\n", *lo, *hi);
  for (float v : phi)
    if (!(v >= 0.0f && v <= 1.0f)) return 1;
  return (*lo == 0.0f && *hi == 1.0f) ? 0 : 1;
}
