// hgdeform batch: placeholder until the batch runner lands (issue 6).
#include <cstdio>

namespace hgdcli {
int runBatch(int, char**) {
  std::fprintf(stderr, "hgdeform batch: not built yet\n");
  return 2;
}
}  // namespace hgdcli
