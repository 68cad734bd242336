// How a point blends the transforms of the two clusters that bracket its harmonic value.
#pragma once

#include <string>

namespace hgd {

/// How two cluster transforms are blended between isovalues.
enum class Blend {
  Linear,    ///< the paper's eq. (1): (1 - a) T_lo + a T_hi; shrinks where the rotations differ
  Rotation,  ///< rigid parts blended: each cluster's rotation (polar decomposition) about its
             ///< barycentre; rotations along the shortest arc (normalised quaternion lerp), the
             ///< image of the pair's centre linearly. No shrinking where clusters turn apart.
};

/// "linear" or "rotation".
const char* blendName(Blend blend);

/// Parses "linear" or "rotation"; false for anything else.
bool parseBlend(const std::string& text, Blend& blend);

}  // namespace hgd
