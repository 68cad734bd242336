// One scan split across MPI ranks (`mpirun hgdeform deform --mpi`): MPI as hgd::StreamRanks.
#pragma once

#include <memory>
#include <string>

#include "hgdeform/io/records.h"

#ifdef HGD_HAVE_MPI
#include <mpi.h>
#endif

namespace hgdcli {

/// MPI for one run: initialised when the program was started by an MPI launcher (mpirun,
/// srun), finalised when this goes. Without one, or in a build without MPI, one process.
class StreamMpi {
 public:
  StreamMpi();
  ~StreamMpi();
  StreamMpi(const StreamMpi&) = delete;
  StreamMpi& operator=(const StreamMpi&) = delete;
  /// Whether this build has MPI at all.
  static bool available();
  /// Whether an MPI launcher started the program (MPI was initialised).
  bool launched() const { return launched_; }
  int rank() const { return rank_; }
  int size() const { return size_; }
  /// The end of a run, on every rank: returns the worst exit status of all ranks once every
  /// rank got here. A rank whose run failed (`status` non-zero, `error` why) is said by rank 0
  /// (which says its own before calling this) or, when rank 0's succeeded, by itself. When not
  /// every rank gets here in 30 seconds, a rank failed alone while the others wait for it: this
  /// rank says its error and aborts the job (MPI_Abort: the launcher ends every rank).
  int finish(int status, const std::string& error);
  /// The ranks as a streamed run takes them (null for one process).
  hgd::StreamRanks* ranks() { return size_ > 1 ? ranks_.get() : nullptr; }

 private:
  bool launched_ = false;
#ifdef HGD_HAVE_MPI
  MPI_Comm finish_comm_ = MPI_COMM_NULL;  ///< finish()'s own communicator
#endif
  int rank_ = 0, size_ = 1;
  std::unique_ptr<hgd::StreamRanks> ranks_;
};

}  // namespace hgdcli
