#include "hgdeform/version.h"

namespace hgd {

const char* version() {
  return HGDEFORM_VERSION;
}

}  // namespace hgd
