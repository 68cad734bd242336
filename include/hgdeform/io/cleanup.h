// Interrupted runs leave no partial file: the signals that end a process remove the temporary
// files of the writes in progress (every writer of <hgdeform/io.h> writes to a temporary file
// beside its output and renames it when complete).
#pragma once

namespace hgd {

/// Installs, for SIGINT, SIGTERM, SIGHUP, SIGPIPE, SIGQUIT, SIGUSR1, SIGUSR2, SIGALRM, SIGVTALRM,
/// SIGXFSZ (an output past `ulimit -f`) and SIGXCPU, a handler that removes the temporary files
/// of writes in progress (removeTemporaryFiles, <hgdeform/io.h>), then calls `also(signal)` when
/// given (it must be async-signal-safe), then ends the process by the same signal with its
/// default action, so that the exit status says it was killed (a shell shows 128 + the number:
/// 130 for SIGINT, 143 for SIGTERM). A signal that is ignored when this is called (as nohup
/// leaves SIGHUP) stays ignored. Every hgdeform tool calls it before its work; a program using
/// the library may.
void removeTemporaryFilesOnSignals(void (*also)(int) = nullptr) noexcept;

}  // namespace hgd
