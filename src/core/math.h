// cambium — small scalar functions shared by the models.
#pragma once

#include <algorithm>

namespace cambium {

/// 0 below e0, 1 above e1, the cubic 3u^2 - 2u^3 of u = (x - e0) / (e1 - e0)
/// between (C1, flat at both ends); a step at e1 when e1 <= e0.
inline double smoothstep(double e0, double e1, double x)
{
    if (!(e1 > e0))
        return x >= e1 ? 1.0 : 0.0;
    const double u = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
    return u * u * (3.0 - 2.0 * u);
}

}  // namespace cambium
