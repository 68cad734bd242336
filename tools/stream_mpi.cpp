// MPI as the ranks of a split streamed run (stream_mpi.h): the passes' findings gathered by
// broadcasts from each rank in turn (no 2 GiB limit on a part), the records written with MPI-IO
// at their place in the one output file.
#include "stream_mpi.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include "hgdeform/io/io.h"

#ifdef HGD_HAVE_MPI
#include <mpi.h>
#endif

namespace hgdcli {

#ifdef HGD_HAVE_MPI
namespace {

std::string mpiError(int code) {
  char text[MPI_MAX_ERROR_STRING];
  int length = 0;
  MPI_Error_string(code, text, &length);
  return std::string(text, static_cast<std::size_t>(length));
}

class MpiRanks final : public hgd::StreamRanks {
 public:
  MpiRanks(int rank, int size) : rank_(rank), size_(size) {}
  int rank() const override { return rank_; }
  int size() const override { return size_; }

  std::vector<std::string> allgather(const std::string& mine) override {
    std::vector<std::string> all(static_cast<std::size_t>(size_));
    for (int r = 0; r < size_; ++r) {
      std::string& part = all[static_cast<std::size_t>(r)];
      unsigned long long n = r == rank_ ? mine.size() : 0;
      MPI_Bcast(&n, 1, MPI_UNSIGNED_LONG_LONG, r, MPI_COMM_WORLD);
      part = r == rank_ ? mine : std::string(static_cast<std::size_t>(n), '\0');
      constexpr unsigned long long kChunk = 1ull << 30;  // MPI's counts are ints
      for (unsigned long long at = 0; at < n; at += kChunk)
        MPI_Bcast(part.data() + at, static_cast<int>(std::min(kChunk, n - at)), MPI_BYTE, r, MPI_COMM_WORLD);
    }
    return all;
  }

  std::string writeAt(const std::string& file, std::uint64_t at,
                      const std::function<void(hgd::RecordSink&)>& part) override {
    MPI_File fh = MPI_FILE_NULL;
    // Each rank on its own (MPI_COMM_SELF: a rank that cannot open the file makes no collective
    // call the others wait for; the gather after this says who failed). The file exists: rank
    // 0's temporary.
    int code = MPI_File_open(MPI_COMM_SELF, file.c_str(), MPI_MODE_WRONLY, MPI_INFO_NULL, &fh);
    std::string failed;
    if (code != MPI_SUCCESS) {
      failed = file + ": cannot open for writing the records of rank " + std::to_string(rank_) + ": " +
               mpiError(code);
    } else {
      struct Sink final : hgd::RecordSink {
        MPI_File fh;
        std::uint64_t at;
        const std::string* file;
        void write(const std::uint8_t* p, std::size_t n) override {
          while (n > 0) {
            const int count = static_cast<int>(std::min<std::size_t>(n, std::size_t{1} << 30));
            MPI_Status status;
            const int c = MPI_File_write_at(fh, static_cast<MPI_Offset>(at), p, count, MPI_BYTE, &status);
            if (c != MPI_SUCCESS) throw hgd::IoError(*file + ": cannot write: " + mpiError(c));
            p += count;
            n -= static_cast<std::size_t>(count);
            at += static_cast<std::uint64_t>(count);
          }
        }
      } sink;
      sink.fh = fh;
      sink.at = at;
      sink.file = &file;
      try {
        part(sink);
      } catch (const std::exception& e) {
        failed = e.what();
      }
      code = MPI_File_close(&fh);
      if (code != MPI_SUCCESS && failed.empty()) failed = file + ": cannot write: " + mpiError(code);
    }
    return failed;
  }

 private:
  int rank_, size_;
};

}  // namespace
#endif

bool StreamMpi::available() {
#ifdef HGD_HAVE_MPI
  return true;
#else
  return false;
#endif
}

StreamMpi::StreamMpi() {
#ifdef HGD_HAVE_MPI
  if (std::getenv("OMPI_COMM_WORLD_SIZE") || std::getenv("PMI_SIZE") || std::getenv("PMIX_RANK")) {
    int provided = 0;
    MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
    launched_ = true;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
    ranks_ = std::make_unique<MpiRanks>(rank_, size_);
    MPI_Comm_dup(MPI_COMM_WORLD, &finish_comm_);
  }
#endif
}

int StreamMpi::finish(int status, const std::string& error) {
#ifdef HGD_HAVE_MPI
  if (launched_) {
    // Every rank's status, on a communicator of its own (a rank still waiting in a gather of the
    // run, for one that failed alone, makes no mismatched call): when every rank gets here.
    std::vector<int> all(static_cast<std::size_t>(size_), 0);
    MPI_Request request;
    MPI_Iallgather(&status, 1, MPI_INT, all.data(), 1, MPI_INT, finish_comm_, &request);
    int done = 0;
    for (int waited = 0; waited < 3000 && !done; ++waited) {
      MPI_Test(&request, &done, MPI_STATUS_IGNORE);
      if (!done) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    if (!done) {  // a rank failed alone: the others wait for it in the run; said here, ended here
      if (rank_ != 0) std::fprintf(stderr, "hgdeform deform: rank %d: %s\n", rank_, error.c_str());
      std::fflush(stderr);
      MPI_Abort(MPI_COMM_WORLD, status != 0 ? status : 1);
    }
    int worst = 0;
    for (const int s : all) worst = std::max(worst, s);
    // Rank 0 said its own error already; another rank says its own when rank 0 had none.
    if (rank_ != 0 && status != 0 && all[0] == 0) {
      std::fprintf(stderr, "hgdeform deform: rank %d: %s\n", rank_, error.c_str());
      std::fflush(stderr);
    }
    return worst;
  }
#endif
  (void)error;
  return status;
}

StreamMpi::~StreamMpi() {
#ifdef HGD_HAVE_MPI
  if (!launched_) return;
  MPI_Comm_free(&finish_comm_);
  MPI_Finalize();
#endif
}

}  // namespace hgdcli
