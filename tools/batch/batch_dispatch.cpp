// hgdeform batch: who processes which scan. Without MPI a pool of --jobs threads; under mpirun
// the ranks, each taking the next scan from a counter on rank 0.
#include <omp.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <cstdlib>
#include <future>
#include <mutex>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "batch_internal.h"
#ifdef HGD_HAVE_MPI
#include <mpi.h>
#endif

namespace hgdcli {
namespace batch {

namespace {

/// Dispatch order: largest first, so that a big scan started last does not hold up the end.
std::vector<std::size_t> largestFirst(const std::vector<Scan>& scans) {
  std::vector<std::size_t> order(scans.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return scans[a].size > scans[b].size; });
  return order;
}

/// OpenMP threads for each of `concurrent` scans: the cores (as this process may use them) shared
/// out, at most OMP_NUM_THREADS when that is set.
int ompThreadsPerScan(int concurrent) {
  int n = std::max(1, omp_get_num_procs() / std::max(1, concurrent));
  if (const char* env = std::getenv("OMP_NUM_THREADS")) {
    const long cap = std::strtol(env, nullptr, 10);
    if (cap >= 1) n = std::min(n, static_cast<int>(std::min(cap, 1024L)));
  }
  return n;
}

}  // namespace

/// The thread pool: `jobs` workers take the next scan until none is left.
std::vector<ScanResult> runThreads(const std::vector<Scan>& scans, const Context& ctx, Progress& progress) {
  const std::size_t n = scans.size();
  std::vector<ScanResult> results(n);
  if (n == 0) return results;
  std::vector<std::size_t> order;
  if (ctx.cfg.jobs == 1) {
    for (std::size_t i = 0; i < n; ++i) order.push_back(i);  // the listing's order: easy to follow
  } else {
    order = largestFirst(scans);
  }
  const int threads_per_scan = ompThreadsPerScan(ctx.cfg.jobs);
  const std::size_t workers = std::min<std::size_t>(static_cast<std::size_t>(ctx.cfg.jobs), n);
  std::atomic<std::size_t> next{0};
  std::mutex m;
  std::condition_variable cv;
  std::size_t running = workers;
  auto work = [&] {
    omp_set_num_threads(threads_per_scan);  // this thread's parallel regions
    for (;;) {
      const std::size_t k = next.fetch_add(1);
      if (k >= n) break;
      const Scan& s = scans[order[k]];
      progress.started(s.rel);
      results[order[k]] = processScan(s, ctx);
      progress.finished(results[order[k]]);
    }
    std::lock_guard<std::mutex> lock(m);
    if (--running == 0) cv.notify_all();
  };
  std::vector<std::thread> pool;
  for (std::size_t i = 0; i < workers; ++i) pool.emplace_back(work);
  {
    std::unique_lock<std::mutex> lock(m);
    while (!cv.wait_for(lock, std::chrono::seconds(1), [&] { return running == 0; })) {
      lock.unlock();
      progress.tick();
      lock.lock();
    }
  }
  for (auto& t : pool) t.join();
  return results;
}

// --- MPI -------------------------------------------------------------------------------------

MpiSession::MpiSession() {
#ifdef HGD_HAVE_MPI
  if (std::getenv("OMPI_COMM_WORLD_SIZE") || std::getenv("PMI_SIZE")) {
    int provided = 0;
    // Only the main thread calls MPI; the scan runs on a worker thread meanwhile.
    MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
    active = true;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
  }
#endif
}

MpiSession::~MpiSession() {
#ifdef HGD_HAVE_MPI
  if (active) MPI_Finalize();
#endif
}

void MpiSession::barrier() const {
#ifdef HGD_HAVE_MPI
  if (active) MPI_Barrier(MPI_COMM_WORLD);
#endif
}

int MpiSession::broadcast(int value) const {
#ifdef HGD_HAVE_MPI
  if (active) MPI_Bcast(&value, 1, MPI_INT, 0, MPI_COMM_WORLD);
#endif
  return value;
}

#ifdef HGD_HAVE_MPI
namespace {

/// FNV-1a of the list, for checking that every MPI rank sees the same scans.
std::uint64_t listHash(const std::vector<Scan>& scans) {
  std::uint64_t h = 1469598103934665603ull;
  auto add = [&](const std::string& s) {
    for (unsigned char ch : s) h = (h ^ ch) * 1099511628211ull;
    h = (h ^ 0xff) * 1099511628211ull;
  };
  for (const auto& s : scans) {
    add(s.rel);
    add(std::to_string(s.size));
  }
  return h;
}

/// Ranks on this node, so that they share its cores.
int ranksOnThisNode() {
  MPI_Comm node;
  MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node);
  int n = 1;
  MPI_Comm_size(node, &n);
  MPI_Comm_free(&node);
  return n;
}

}  // namespace

/// Every rank holds the same list. Scans, largest first, are handed out by a counter on rank 0
/// (MPI_Fetch_and_op, passive target), one at a time per rank. Returns on rank 0 the results of
/// all ranks (sorted by file), on the others their own.
std::vector<ScanResult> runMpi(const std::vector<Scan>& scans, const Context& ctx, Progress& progress,
                               const MpiSession& mpi) {
  // Same scans everywhere? (A rank on a node with a stale view of a shared file system would
  // otherwise process the wrong files.)
  unsigned long long mine = listHash(scans), root = mine;
  MPI_Bcast(&root, 1, MPI_UNSIGNED_LONG_LONG, 0, MPI_COMM_WORLD);
  int differs = root != mine ? 1 : 0, any_differs = 0;
  MPI_Allreduce(&differs, &any_differs, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  if (any_differs) throw std::runtime_error("the MPI ranks do not see the same scans in the input directory");

  const int threads_per_scan = ompThreadsPerScan(ranksOnThisNode());
  const std::vector<std::size_t> order = largestFirst(scans);
  const long n = static_cast<long>(scans.size());

  long* counter = nullptr;
  MPI_Win win;
  MPI_Win_allocate(mpi.rank == 0 ? static_cast<MPI_Aint>(sizeof(long)) : 0, sizeof(long), MPI_INFO_NULL,
                   MPI_COMM_WORLD, &counter, &win);
  if (mpi.rank == 0) {
    MPI_Win_lock(MPI_LOCK_EXCLUSIVE, 0, 0, win);
    *counter = 0;
    MPI_Win_unlock(0, win);
  }
  MPI_Barrier(MPI_COMM_WORLD);
  MPI_Win_lock_all(0, win);

  std::vector<ScanResult> results;
  for (;;) {
    const long one = 1;
    long k = 0;
    MPI_Fetch_and_op(&one, &k, MPI_LONG, 0, 0, MPI_SUM, win);
    MPI_Win_flush(0, win);
    if (k >= n) break;
    const Scan& s = scans[order[static_cast<std::size_t>(k)]];
    progress.started(s.rel);
    auto future = std::async(std::launch::async, [&] {
      omp_set_num_threads(threads_per_scan);
      return processScan(s, ctx);
    });
    // Keep this rank's MPI progressing meanwhile: with some transports the counter on rank 0
    // only advances when rank 0 enters the library.
    while (future.wait_for(std::chrono::milliseconds(20)) != std::future_status::ready) {
      int flag = 0;
      MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, MPI_STATUS_IGNORE);
    }
    results.push_back(future.get());
    progress.finished(results.back(), static_cast<std::size_t>(k) + 1);
  }
  MPI_Win_unlock_all(win);
  MPI_Win_free(&win);

  // Gather the results on rank 0 as JSON text.
  nlohmann::json array = nlohmann::json::array();
  for (const auto& r : results) array.push_back(batch::toJson(r));
  const std::string text = array.dump();
  int len = static_cast<int>(text.size());
  std::vector<int> lens(static_cast<std::size_t>(mpi.size)), displs(static_cast<std::size_t>(mpi.size));
  MPI_Gather(&len, 1, MPI_INT, lens.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  std::vector<char> all;
  if (mpi.rank == 0) {
    long long total = 0;
    for (int r = 0; r < mpi.size; ++r) {
      displs[static_cast<std::size_t>(r)] = static_cast<int>(total);
      total += lens[static_cast<std::size_t>(r)];
    }
    all.resize(static_cast<std::size_t>(std::max(total, 1LL)));
  }
  MPI_Gatherv(text.data(), len, MPI_CHAR, all.data(), lens.data(), displs.data(), MPI_CHAR, 0,
              MPI_COMM_WORLD);
  if (mpi.rank != 0) return results;
  std::vector<ScanResult> merged;
  for (int r = 0; r < mpi.size; ++r) {
    const auto ri = static_cast<std::size_t>(r);
    const auto j = nlohmann::json::parse(all.begin() + displs[ri], all.begin() + displs[ri] + lens[ri]);
    for (const auto& e : j) merged.push_back(batch::fromJson(e));
  }
  std::sort(merged.begin(), merged.end(),
            [](const ScanResult& a, const ScanResult& b) { return a.file < b.file; });
  return merged;
}
#endif

}  // namespace batch
}  // namespace hgdcli
