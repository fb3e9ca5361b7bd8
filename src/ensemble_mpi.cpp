// The MPI runner of `lgvi ensemble` (ensemble.hpp): started by mpirun/srun
// as K ranks. Rank 0 prepares the output folder (or reads it back with
// --resume), then hands out members one at a time to whichever rank asks
// (dynamic hand-out: long and short members mix) and appends each finished
// row to the journal as it arrives; every rank, rank 0 included (on a second
// thread), runs members. The rows do not depend on K: each member's numbers
// come from (seed, index) and each run is deterministic.
//
// Messages: a worker sends REQUEST carrying its last row (empty the first
// time); rank 0 answers WORK with a member index or STOP. So each member
// costs two messages, and rank 0's work per member is one receive, one send
// and one append: at ~10 us per member, rank 0 keeps up with thousands of
// ranks as long as a member takes more than K x 10 us (a member of 1e4
// steps takes ~3 ms: ~300 ranks per coordinator; beyond, members should be
// made longer or handed out in blocks).
#include "ensemble.hpp"

#include <lgvi/error.hpp>

#include <fmt/format.h>

#include <mpi.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <iostream>
#include <mutex>
#include <thread>

namespace lgvi::app {


namespace {

enum Tag : int { kRequest = 1, kWork = 2, kStop = 3, kAbort = 4 };

/// One message of text to rank 0 (a row, or a failure's message).
void send_text(const std::string& text, int tag) {
  MPI_Send(text.data(), static_cast<int>(text.size()), MPI_CHAR, 0, tag, MPI_COMM_WORLD);
}

std::string receive_text(const MPI_Status& status) {
  int count = 0;
  MPI_Get_count(&status, MPI_CHAR, &count);
  std::string text(static_cast<std::size_t>(count), '\0');
  MPI_Recv(text.data(), count, MPI_CHAR, status.MPI_SOURCE, status.MPI_TAG, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
  return text;
}

/// Ranks 1..K-1: ask for a member, run it, send its row with the next request.
int worker_loop(const EnsemblePlan& plan, const std::string& dir) {
  std::string last;
  for (;;) {
    send_text(last, kRequest);
    std::int64_t index = -1;
    MPI_Status status;
    MPI_Recv(&index, 1, MPI_INT64_T, 0, MPI_ANY_TAG, MPI_COMM_WORLD, &status);
    if (status.MPI_TAG == kStop) return 0;
    try {
      last = run_member(plan, index, 1, ensemble_detail::trajectory_dir(dir, plan, index));
    } catch (const std::exception& e) {
      send_text(e.what(), kAbort);
      return 1;
    }
    if (last.empty()) {  // stopped by a signal within the member
      send_text("", kRequest);
      MPI_Recv(&index, 1, MPI_INT64_T, 0, MPI_ANY_TAG, MPI_COMM_WORLD, &status);
      return 0;
    }
  }
}

}  // namespace

int run_ensemble_mpi(const std::string& sweep_path, const EnsembleOptions& opt) {
  using namespace ensemble_detail;
  int provided = 0;
  MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
  int rank = 0, ranks = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);
  struct Finalize {
    ~Finalize() { MPI_Finalize(); }
  } finalize;
  Signals signals;

  // Rank 0 prepares the folder; the others read the plan from its copies.
  Prepared p;
  std::string failure;
  if (rank == 0) {
    try {
      p = prepare(sweep_path, opt);
    } catch (const std::exception& e) {
      failure = e.what();
    }
  }
  int ok = failure.empty() ? 1 : 0;
  MPI_Bcast(&ok, 1, MPI_INT, 0, MPI_COMM_WORLD);
  if (!ok) {
    if (rank == 0) throw InvalidInput(failure);
    return 2;
  }
  std::string dir = p.dir;
  int length = static_cast<int>(dir.size());
  MPI_Bcast(&length, 1, MPI_INT, 0, MPI_COMM_WORLD);
  dir.resize(static_cast<std::size_t>(length));
  MPI_Bcast(dir.data(), length, MPI_CHAR, 0, MPI_COMM_WORLD);
  if (rank != 0) {
    EnsemblePlan plan;
    try {
      plan = plan_of_folder(dir);
    } catch (const std::exception& e) {
      send_text(e.what(), kAbort);
      return 2;
    }
    return worker_loop(plan, dir);
  }

  // Rank 0: the pending members, handed out in index order to whoever asks.
  std::vector<std::int64_t> pending;
  std::int64_t done = 0, failed = 0;
  for (std::int64_t i = 0; i < p.plan.members(); ++i) {
    if (p.rows[static_cast<std::size_t>(i)].empty()) {
      pending.push_back(i);
    } else {
      ++done;
      failed += row_failed(p.rows[static_cast<std::size_t>(i)], p.plan) ? 1 : 0;
    }
  }
  std::mutex mutex;
  std::size_t next = 0;
  std::string abort_message;
  auto take = [&](std::int64_t& i) {
    std::lock_guard<std::mutex> lock(mutex);
    if (next >= pending.size() || stop_signal() != 0 || !abort_message.empty()) return false;
    i = pending[next++];
    return true;
  };
  auto record = [&](const std::string& row) {
    std::lock_guard<std::mutex> lock(mutex);
    const auto i = static_cast<std::size_t>(std::stoll(row.substr(0, row.find(','))));
    append_journal(dir, row);
    p.rows[i] = row;
    ++done;
    failed += row_failed(row, p.plan) ? 1 : 0;
  };
  // Rank 0's own member runs, on a second thread (MPI stays on this one).
  std::atomic<bool> local_done{false};
  std::thread local([&] {
    std::int64_t i = 0;
    while (take(i)) {
      try {
        const std::string row = run_member(p.plan, i, 1, trajectory_dir(dir, p.plan, i));
        if (row.empty()) break;
        record(row);
      } catch (const std::exception& e) {
        std::lock_guard<std::mutex> lock(mutex);
        abort_message = e.what();
        break;
      }
    }
    local_done = true;
  });
  int active = ranks - 1;
  while (active > 0) {
    int flag = 0;
    MPI_Status status;
    MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &status);
    if (!flag) {
      // Open MPI's blocking receive spins a core; rank 0 shares its cores with a member run.
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      continue;
    }
    const std::string text = receive_text(status);
    if (status.MPI_TAG == kAbort) {
      std::lock_guard<std::mutex> lock(mutex);
      if (abort_message.empty()) abort_message = "rank " + std::to_string(status.MPI_SOURCE) + ": " + text;
      --active;
      continue;
    }
    if (!text.empty()) record(text);
    std::int64_t i = -1;
    if (take(i)) {
      MPI_Send(&i, 1, MPI_INT64_T, status.MPI_SOURCE, kWork, MPI_COMM_WORLD);
    } else {
      MPI_Send(&i, 1, MPI_INT64_T, status.MPI_SOURCE, kStop, MPI_COMM_WORLD);
      --active;
    }
  }
  local.join();
  if (!abort_message.empty()) {
    write_members_csv(dir, p.plan, p.rows);
    throw InvalidInput(abort_message);
  }
  return finish(p, done, failed, opt);
}

}  // namespace lgvi::app
