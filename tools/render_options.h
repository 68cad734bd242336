// The picture options hgdeform-render and hgdeform-view share: --up (which axis points up) and
// --view (where the eye is), checked as they are parsed.
#pragma once

#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <cstdio>
#include <exception>
#include <optional>
#include <string>

#include "hgdeform/render/render.h"

namespace hgdcli {

/// --up AXIS: x|y|z|-x|-y|-z|auto, checked by hgd::upAxis.
inline CLI::Option* addUpOption(CLI::App& app, std::string& up, const std::string& help) {
  return app.add_option("--up", up, help)
      ->check(CLI::Validator(
          [](std::string& s) -> std::string {
            try {
              hgd::upAxis(s, {});
            } catch (const std::exception& e) {
              return e.what();
            }
            return {};
          },
          "", "axis"))
      ->type_name("AXIS");
}

/// --view x,y,z: the direction from the target to the eye, three finite numbers not all 0.
inline CLI::Option* addViewOption(CLI::App& app, std::optional<Eigen::Vector3f>& view,
                                  const std::string& help) {
  return app.add_option("--view", help)
      ->check(CLI::Validator(
          [&view](std::string& s) -> std::string {
            Eigen::Vector3f v;
            int used = 0;
            if (std::sscanf(s.c_str(), "%f,%f,%f%n", &v.x(), &v.y(), &v.z(), &used) != 3 ||
                static_cast<std::size_t>(used) != s.size() || !v.allFinite() || v.norm() == 0)
              return "must be three finite numbers x,y,z, not all 0 (got '" + s + "')";
            view = v;
            return {};
          },
          "", "direction"))
      ->type_name("x,y,z");
}

}  // namespace hgdcli
