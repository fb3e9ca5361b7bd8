// The MPI runner of `lgvi ensemble` (ensemble.hpp): started by mpirun/srun
// as K ranks. Rank 0 prepares the output folder (or reads it back with
// --resume), then hands out members one at a time to whichever rank asks
// (dynamic hand-out: long and short members mix) and appends each finished
// row to the journal as it arrives; every rank, rank 0 included (on threads
// beside its coordinator), runs --threads members at once (default 1). The rows do not depend on K: each member's numbers
// come from (seed, index) and each run is deterministic.
//
// Messages: a worker keeps REQUESTs outstanding (about 10 ms of members in
// reserve, worker_loop), each carrying its last row (or nothing); rank 0
// answers each with WORK (a member index) or STOP. So each member costs two
// messages (a few more while a worker fills its reserve), and rank 0's work per member is
// one receive, one send and one append: one coordinator keeps up with K ranks
// while a member takes more than K times that (the estimate:
// docs/guide/ensembles.md); beyond, members should be made longer or handed
// out in blocks.
//
// Every send is non-blocking (Outbox). Open MPI's blocking MPI_Send of a
// small message waits in ompi_sync_wait_mt, spinning, until the receiver next
// enters MPI: a worker sending its row would wait for rank 0's coordinator,
// which sleeps between polls and shares a core with rank 0's member runs (so
// it is woken late); rank 0 replying would wait for a worker busy in a member
// (measured: docs/benchmarks.md, "Ensembles: overhead and scaling").
#include "app/ensemble.hpp"

#include <lgvi/error.hpp>

#include <fmt/format.h>

#include <mpi.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <deque>
#include <iostream>
#include <iterator>
#include <list>
#include <mutex>
#include <thread>

namespace lgvi::app {


namespace {

enum Tag : int { kRequest = 1, kWork = 2, kStop = 3, kAbort = 4, kResult = 5, kDone = 6 };

/// Sends without waiting for the receiver: each message's bytes are kept
/// until MPI reports the send complete (checked at every post, and by
/// flush()). Messages between two ranks arrive in the order posted (MPI's
/// non-overtaking rule holds for non-blocking sends as for blocking ones).
class Outbox {
 public:
  Outbox() = default;
  Outbox(const Outbox&) = delete;
  Outbox& operator=(const Outbox&) = delete;
  ~Outbox() { flush(); }

  /// Text (a row, a message), received as MPI_CHAR.
  void post(std::string text, int dest, int tag) {
    Pending& m = add();
    m.text = std::move(text);
    MPI_Isend(m.text.data(), static_cast<int>(m.text.size()), MPI_CHAR, dest, tag, MPI_COMM_WORLD, &m.request);
  }
  /// A member index, received as one MPI_INT64_T.
  void post_index(std::int64_t index, int dest, int tag) {
    Pending& m = add();
    m.index = index;
    MPI_Isend(&m.index, 1, MPI_INT64_T, dest, tag, MPI_COMM_WORLD, &m.request);
  }
  /// Waits until every message posted has been sent (before MPI_Finalize).
  void flush() {
    for (Pending& m : pending_) MPI_Wait(&m.request, MPI_STATUS_IGNORE);
    pending_.clear();
  }

 private:
  struct Pending {
    std::string text;
    std::int64_t index = 0;
    MPI_Request request = MPI_REQUEST_NULL;
  };
  /// Drops the messages already sent; a slot for the next.
  Pending& add() {
    for (auto it = pending_.begin(); it != pending_.end();) {
      int done = 0;
      MPI_Test(&it->request, &done, MPI_STATUS_IGNORE);
      it = done ? pending_.erase(it) : std::next(it);
    }
    return pending_.emplace_back();
  }
  std::list<Pending> pending_;  // a list: each message's bytes stay where MPI was told they are
};

/// One message of text to rank 0 (a row, or a failure's message).
void send_text(Outbox& out, const std::string& text, int tag) { out.post(text, 0, tag); }

std::string receive_text(const MPI_Status& status) {
  int count = 0;
  MPI_Get_count(&status, MPI_CHAR, &count);
  std::string text(static_cast<std::size_t>(count), '\0');
  MPI_Recv(text.data(), count, MPI_CHAR, status.MPI_SOURCE, status.MPI_TAG, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
  return text;
}

/// Ranks 1..K-1, running `runners` members at once (--threads; one thread
/// each, MPI only on this one: MPI_THREAD_FUNNELED). A worker keeps a reserve
/// of members asked for (received or still on their way) besides those it
/// runs, so that the next index is already here when a member ends (no round
/// trip between members, and no wait in a blocking receive, which Open MPI
/// spins). The reserve covers kReserveTime of work per runner at the mean
/// duration of the members run so far (at least 1, at most kMaxReserve
/// members per runner): rank 0's coordinator answers within its polling
/// interval plus the wait for a core it shares with member runs (a few ms),
/// while a worker holding more than that would only leave the last members
/// unevenly spread. A request carries the last member's row (or nothing);
/// each is answered WORK (an index) or STOP. After a STOP, the members
/// already received still run and their rows go back as RESULT; DONE ends
/// the rank.
int worker_loop(const EnsemblePlan& plan, const std::string& dir, Outbox& out, int runners) {
  constexpr double kReserveTime = 0.010;  // seconds
  constexpr std::size_t kMaxReserve = 8;
  // Shared with the runner threads, under `mutex`.
  std::mutex mutex;
  std::condition_variable work_ready, run_ended;
  std::deque<std::int64_t> queue;
  std::deque<ensemble_detail::TimedRow> finished;
  bool no_more = false;   // no index will be added to the queue: runners leave once it is empty
  std::string abort_message;
  int running = runners;  // runner threads not yet left
  auto runner = [&] {
    std::unique_lock<std::mutex> lock(mutex);
    for (;;) {
      work_ready.wait(lock, [&] { return !queue.empty() || no_more; });
      if (queue.empty()) break;
      const std::int64_t index = queue.front();
      queue.pop_front();
      lock.unlock();
      ensemble_detail::TimedRow run;
      std::string failure;
      try {
        run = ensemble_detail::run_member_timed(plan, index, dir);
      } catch (const std::exception& e) {
        failure = e.what();
      }
      lock.lock();
      if (!failure.empty()) {
        if (abort_message.empty()) abort_message = failure;
        queue.clear();
      } else if (run.row.empty()) {  // stopped by a signal within the member: not a result
        queue.clear();
      } else {
        finished.push_back(std::move(run));
      }
      run_ended.notify_one();
    }
    --running;
    run_ended.notify_one();
  };

  std::size_t outstanding = 0;
  bool stopped = false;
  double run_seconds = 0.0;
  std::int64_t runs = 0;
  auto request = [&](const std::string& row) {
    send_text(out, row, kRequest);
    ++outstanding;
  };
  std::vector<std::thread> threads;
  threads.reserve(static_cast<std::size_t>(runners));
  for (int t = 0; t < runners; ++t) threads.emplace_back(runner);
  for (int t = 0; t <= runners; ++t) request("");
  std::unique_lock<std::mutex> lock(mutex);
  for (;;) {
    // Replies from rank 0, without blocking while there is work here.
    lock.unlock();
    std::size_t received = 0;
    while (outstanding > 0) {
      int ready = 0;
      MPI_Status status;
      MPI_Iprobe(0, MPI_ANY_TAG, MPI_COMM_WORLD, &ready, &status);
      if (!ready) break;
      std::int64_t index = -1;
      MPI_Recv(&index, 1, MPI_INT64_T, 0, MPI_ANY_TAG, MPI_COMM_WORLD, &status);
      --outstanding;
      ++received;
      std::lock_guard<std::mutex> guard(mutex);
      if (status.MPI_TAG == kWork && abort_message.empty() && stop_signal() == 0) {
        queue.push_back(index);
        work_ready.notify_one();
      } else {
        stopped = true;
      }
    }
    lock.lock();
    if (!abort_message.empty() || stop_signal() != 0) {
      stopped = true;
      queue.clear();
    }
    // Rows of finished runs: each goes back with the next request, or as a
    // RESULT after a STOP.
    while (!finished.empty()) {
      ensemble_detail::TimedRow run = std::move(finished.front());
      finished.pop_front();
      run_seconds += run.seconds;
      ++runs;
      run.row.push_back('\n');  // a row has no newline: the wall time follows one
      fmt::format_to(std::back_inserter(run.row), "{:.17g}", run.seconds);
      if (!stopped) {
        request(run.row);
      } else {
        send_text(out, run.row, kResult);
      }
    }
    if (!stopped) {
      std::size_t reserve = 1;
      if (runs > 0) {
        const double mean = run_seconds / static_cast<double>(runs);
        reserve = static_cast<std::size_t>(std::clamp(std::ceil(kReserveTime / std::max(mean, 1e-9)), 1.0,
                                                      static_cast<double>(kMaxReserve)));
      }
      while (queue.size() + outstanding < reserve * static_cast<std::size_t>(runners)) request("");
    }
    if (stopped && outstanding == 0 && !no_more) {
      no_more = true;
      work_ready.notify_all();
    }
    if (running == 0 && finished.empty()) break;
    // Wait for a run to end, or poll MPI again shortly (a reply arrives by
    // message, not by this condition).
    if (received == 0) run_ended.wait_for(lock, std::chrono::milliseconds(outstanding > 0 ? 1 : 50));
  }
  lock.unlock();
  for (std::thread& t : threads) t.join();
  if (!abort_message.empty()) {
    send_text(out, abort_message, kAbort);
    return 1;
  }
  send_text(out, "", kDone);
  return 0;
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
  Outbox out;  // after finalize: destroyed (flushed) before MPI_Finalize
  StopSignals signals;
  // Members run at once on each rank: --threads, else 1 (one rank per core
  // is the usual launch; rank 0 runs them beside its coordinator).
  const int runners = std::max(1, opt.threads);

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
      plan = plan_of_folder(dir, false);  // rank 0 has checked every member
    } catch (const std::exception& e) {
      send_text(out, e.what(), kAbort);
      return 2;
    }
    return worker_loop(plan, dir, out, runners);
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
  EnsembleProgress progress(opt, p.plan.members(), done);
  std::mutex mutex;
  std::size_t next = 0;
  std::string abort_message;
  auto take = [&](std::int64_t& i) {
    std::lock_guard<std::mutex> lock(mutex);
    if (next >= pending.size() || stop_signal() != 0 || !abort_message.empty()) return false;
    i = pending[next++];
    return true;
  };
  // A row and the wall time of its run, from the rank that ran it.
  auto record = [&](const std::string& row, double seconds, int from) {
    std::lock_guard<std::mutex> lock(mutex);
    const auto i = static_cast<std::size_t>(std::stoll(row.substr(0, row.find(','))));
    append_journal(dir, row);
    append_timing(dir, static_cast<std::int64_t>(i), seconds, from);
    p.rows[i] = row;
    ++done;
    failed += row_failed(row, p.plan) ? 1 : 0;
    progress(done, failed);
  };
  // A worker's message: its row, a newline, the run's wall time.
  auto record_message = [&](const std::string& text, int from) {
    const std::size_t cut = text.rfind('\n');
    record(text.substr(0, cut), std::strtod(text.c_str() + cut + 1, nullptr), from);
  };
  // Rank 0's own member runs, on `runners` more threads (MPI stays on this one).
  auto local_runs = [&] {
    std::int64_t i = 0;
    while (take(i)) {
      try {
        const auto [row, seconds] = run_member_timed(p.plan, i, dir);
        if (row.empty()) break;
        record(row, seconds, 0);
      } catch (const std::exception& e) {
        std::lock_guard<std::mutex> lock(mutex);
        if (abort_message.empty()) abort_message = e.what();
        break;
      }
    }
  };
  // Rank 0's runners start once every worker has been heard from (its first request, or its
  // abort): a worker reads the plan before it asks, and rank 0's threads, started at once, could
  // take every member of a short ensemble in that time, leaving a rank idle. So every rank gets a
  // member while there are as many pending as ranks.
  std::vector<std::thread> local;
  local.reserve(static_cast<std::size_t>(runners));
  std::vector<bool> heard(static_cast<std::size_t>(ranks), false);
  int unheard = ranks - 1;
  auto start_local_runs = [&] {
    for (int t = 0; t < runners; ++t) local.emplace_back(local_runs);
  };
  if (unheard == 0) start_local_runs();
  int active = ranks - 1;
  while (active > 0) {
    int flag = 0;
    MPI_Status status;
    MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &status);
    if (!flag) {
      // Open MPI's blocking receive spins a core, which rank 0 shares with its member runs.
      // Workers keep ~10 ms of members in reserve (worker_loop), so a reply a few ms late costs
      // them nothing; polling more often takes CPU from rank 0's member runs (500/s here; measured:
      // docs/tuning.md).
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
      continue;
    }
    const std::string text = receive_text(status);
    const bool first_word = !heard[static_cast<std::size_t>(status.MPI_SOURCE)];
    heard[static_cast<std::size_t>(status.MPI_SOURCE)] = true;
    switch (status.MPI_TAG) {
      case kAbort: {
        std::lock_guard<std::mutex> lock(mutex);
        if (abort_message.empty()) abort_message = "rank " + std::to_string(status.MPI_SOURCE) + ": " + text;
        --active;
        break;
      }
      case kDone: --active; break;
      case kResult: record_message(text, status.MPI_SOURCE); break;
      default: {  // kRequest, with the last row
        if (!text.empty()) record_message(text, status.MPI_SOURCE);
        std::int64_t i = -1;
        const bool work = take(i);
        out.post_index(i, status.MPI_SOURCE, work ? kWork : kStop);
      }
    }
    // After the switch, so that a worker's first request is answered before rank 0's threads take.
    if (first_word && --unheard == 0) start_local_runs();
  }
  for (std::thread& t : local) t.join();
  if (!abort_message.empty()) {
    write_members(dir, p.plan, p.rows);
    throw InvalidInput(abort_message);
  }
  return finish(p, done, failed, opt);
}

}  // namespace lgvi::app
