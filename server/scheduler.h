// SPDX-License-Identifier: Apache-2.0
// The farm's bookkeeping: jobs -> frames -> tiles, the priority queue of tiles waiting for a
// worker, leases on the tiles being rendered, speculative duplicates, and the finished tiles a
// client has not yet acknowledged. Plain C++: no gRPC, no Embree, no threads, no I/O. The
// caller serializes access (the coordinator holds one mutex around every call) and supplies the
// time, so tests drive it deterministically.
//
// Every state change goes through the few mutating methods below and is reported, in order, to
// a SchedulerListener: the coordinator uses it to log, to wake streams and to write the changes
// down in its JobStore (job_store.h), from which restore() rebuilds the jobs at restart.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <tuple>
#include <vector>

#include "tile/tile_grid.h"

namespace tessera::server {

using Clock = std::chrono::steady_clock;
using TimePoint = Clock::time_point;
using JobId = std::string;
using WorkerId = uint64_t;
using LeaseId = uint64_t;

// What the coordinator decided at submit time (after validating the scene).
struct JobSpec {
  std::string name;
  std::string bundle_sha256;
  std::string overrides;   // opaque to the scheduler (the service stores serialized overrides)
  int first_frame = 0;
  int last_frame = 0;      // inclusive
  int width = 0, height = 0, spp = 0;
  int tile_size = 32;
  int priority = 0;        // higher first; ties in submit order
  std::string owner;       // the submitting client's identity (request_limits.h); opaque here
  std::string output;      // where a client writes its frames (a serialized JobOutput); opaque here
  // A frame-target job (docs/farm.md, "Frame targets"): each frame's tiles are rendered in passes
  // that the PassPlanner plans, and its tiles are reported finished (tile_finished, then
  // frame_finished) only when its last pass ends. Not stored: the coordinator derives it from the
  // overrides at submit and at restore.
  bool passes = false;

  // Frames x tiles per frame: every tile the job renders.
  int64_t tiles() const;
  // Tiles of one frame: what the scheduler holds in memory for each frame the job has started and
  // a client has not yet acknowledged (a frame not started costs a few bytes, whatever its size).
  int64_t tiles_per_frame() const;
};

// kFailed: every connected worker was blocklisted for the job (see SchedulerOptions::max_faults).
enum class JobState { kQueued, kRunning, kDone, kCancelled, kFailed };
inline bool job_ended(JobState s) { return s == JobState::kDone || s == JobState::kCancelled || s == JobState::kFailed; }
const char* job_state_name(JobState s);

// A finished tile as the scheduler keeps it: the encoded result (opaque bytes, shared so that
// any number of watch streams can send it without copies) and the statistics it reports.
struct TileOutput {
  std::shared_ptr<const std::string> payload;
  uint64_t rays = 0;
  double seconds = 0;
};

struct TileKey {
  JobId job;
  int frame = 0;  // absolute frame number
  int tile = 0;   // row-major index within the frame
};

// A lease covers a span: `count` consecutive tiles of one frame from `tile.tile` (row-major), all
// handed to one worker in one message and written down once (docs/farm.md, "Lease rules"). Each tile's
// result comes on its own; the lease ends when none of its tiles is pending any more.
struct Lease {
  static constexpr int kMaxTiles = 64;  // the width of `pending`
  LeaseId id = 0;
  WorkerId worker = 0;
  TileKey tile;        // the span's first tile
  int count = 1;       // tiles in the span
  // Bit i: tile tile.tile + i still awaits this lease's result (no result yet, not given back,
  // not finished by another copy first).
  uint64_t pending = 1;
  TimePoint issued;
  TimePoint deadline;  // as issued: any message from the worker extends it (its worker's last_seen + lease_timeout)
  bool speculative = false;  // a second copy of a tile already leased to another worker
  // Its pending tiles that have no other copy in flight: the scheduler's count, kept by
  // Scheduler::copies_changed; above 0, the lease is a candidate for a speculative copy.
  int single_tiles = 0;

  bool covers(int t) const { return t >= tile.tile && t < tile.tile + count; }
  bool is_pending(int t) const { return covers(t) && (pending >> (t - tile.tile) & 1); }
  int pending_tiles() const { return __builtin_popcountll(pending); }
};

// A tile handed to a worker: the lease plus everything the worker needs to render it.
struct Assignment {
  Lease lease;
  TileRect rect;
  std::string bundle_sha256;
  std::string overrides;
  std::string plan;  // passes jobs: the tile's sample plan for this pass (opaque here; empty: the first pass)
  TileGrid grid;     // the frame's tiles: a span's other tiles are cut from it
};

// Plans a passes job's next pass when one ends: given every tile's output of the frame (tile
// order) after `passes_done` passes, each tile's plan for the next pass (nullopt: the tile keeps
// its output), or `final` when the frame is done; `error` fails the job (a worker's statistics
// that cannot be planned from).
struct PassDecision {
  bool final = true;
  std::vector<std::optional<std::string>> plans;
  std::string error;
};
using PassPlanner = std::function<PassDecision(const JobId&, int frame, int passes_done,
                                               const std::vector<const TileOutput*>& outputs)>;

enum class LeaseEnd {
  kCompleted,      // its result was accepted
  kLostRace,       // another copy of the tile finished first: the worker should drop it
  kCancelled,      // the job was cancelled: the worker should drop it
  kExpired,        // its worker was silent for longer than the lease timeout: requeued
  kReturned,       // the worker gave it back unrendered
  kWorkerLeft,     // the worker disconnected or was dropped
  kFaulted,        // the worker sent a bad result or could not render: requeued
  kBlocklisted,    // the worker was blocklisted for the job: the worker should drop it
  kStalled,        // its worker returned no result for too long (SchedulerOptions::stall_timeout): requeued
};
const char* lease_end_name(LeaseEnd e);

struct WorkerInfo {
  std::string name;
  std::string peer;
  int threads = 1;
  std::string embree_isa;
  bool reads_spans = false;  // takes leases of several tiles (Register.reads_spans)
};

struct WorkerStats {
  WorkerId id = 0;
  WorkerInfo info;
  TimePoint connected;
  TimePoint last_seen;
  int wanted = 0;          // tiles requested and not yet assigned
  int in_flight = 0;       // tiles of its active leases still to come
  int leases = 0;          // its active leases
  int64_t tiles_done = 0;  // accepted results
  int64_t refused = 0;     // results refused as faults (bad, foreign, for unknown jobs)
  uint64_t rays = 0;
  double seconds = 0;
};

// What every view of a job holds: what it is (id, spec, submit order and time) and where it
// stands (state, end, error, tiles rendered twice). The scheduler's Job, the JobSnapshot it
// reports and the JobRecord the store reads back each start with it, so a field added here
// reaches all three, and one assignment copies it between them (`record.header() = snapshot;`).
struct JobHeader {
  JobId id;
  JobSpec spec;
  uint64_t seq = 0;                // submit order
  JobState state = JobState::kQueued;
  TimePoint submitted;
  std::optional<TimePoint> ended;  // done, cancelled or failed
  std::string error;               // why the job failed
  int64_t duplicates_discarded = 0;  // results for tiles another copy had finished first

  JobHeader& header() { return *this; }
  const JobHeader& header() const { return *this; }
};

struct JobSnapshot : JobHeader {
  int tiles_per_frame = 0;
  int64_t tiles_total = 0;
  int64_t tiles_done = 0;
  int64_t tiles_leased = 0;        // tiles with at least one active lease
  int64_t tiles_resident = 0;      // tiles of its frames held in memory (started, not yet acknowledged)
  // Its next frame cannot start: the tiles held in memory would go over a limit
  // (SchedulerOptions::max_job_tiles or max_resident_tiles) until clients acknowledge frames.
  bool waiting_for_memory = false;
  uint64_t rays = 0;
  double tile_seconds = 0;         // render time of its done tiles, one thread each, summed
  std::vector<std::string> blocklisted;  // worker names refused for this job
  std::vector<int> frames_done;
  std::vector<int> frames_acknowledged;
};

class SchedulerListener {
 public:
  virtual ~SchedulerListener() = default;
  virtual void job_submitted(const JobSnapshot&) {}
  virtual void job_state_changed(const JobId&, JobState) {}
  virtual void job_priority_changed(const JobId&, int /*priority*/) {}
  virtual void tile_leased(const Assignment&) {}
  virtual void lease_ended(const Lease&, LeaseEnd) {}
  // One tile of a span lease lost the race to another copy: its worker should drop that tile (the
  // rest of the span stays its own).
  virtual void span_tile_lost(const Lease&, int /*tile*/) {}
  virtual void tile_finished(const TileKey&, const TileOutput&, WorkerId) {}
  virtual void frame_finished(const JobId&, int frame) {}
  virtual void frame_acknowledged(const JobId&, int frame) {}
  virtual void worker_joined(const WorkerStats&) {}
  virtual void worker_left(const WorkerStats&, std::string_view reason) {}
  // A worker sent a bad result or could not render; `blocklisted` once it reached max_faults.
  virtual void worker_faulted(const JobId&, const WorkerStats&, std::string_view reason, int faults,
                              bool blocklisted) {}
};

// A job as read back from persistent storage (JobStore), for Scheduler::restore().
struct RestoredTile {
  int frame = 0;  // absolute
  int tile = 0;
  TileOutput output;  // payload empty when its frame was acknowledged
};
struct JobRecord : JobHeader {
  std::vector<RestoredTile> done;
  std::vector<int> acknowledged;  // absolute frame numbers
  std::vector<std::string> blocklisted;  // worker names that get no more tiles of the job
};

struct SchedulerOptions {
  // A worker silent for longer than this loses its leases (heartbeats renew them).
  std::chrono::milliseconds lease_timeout{15000};
  // When nothing is queued, idle workers take a second copy of the oldest in-flight tiles.
  bool speculate = true;
  // Factoring (guided self-scheduling): a worker holds at most its share of what is queued, 1 /
  // `factoring` of it, by threads: max(2, ceil(queued / (factoring x threads of every worker)))
  // tiles a thread. Early in a job that is no limit; as the queue runs out, what each worker may
  // hold shrinks to two a thread, so the last tiles are spread over the farm instead of waiting
  // deep in a few workers' queues while others idle and copy them. 0: no cap.
  int factoring = 2;
  int max_wanted_per_worker = 1024;  // caps a worker's standing request
  // Tiles a worker may hold (in leases of any size) before it has returned anything, per thread
  // it declares (at most kMaxCreditThreads of them); each result it returns earns it two more, up
  // to max_wanted_per_worker (a slow start). A session that never renders holds no more than this.
  // 0: no bound (unit tests of other rules).
  int initial_leases_per_thread = 2;
  static constexpr int kMaxCreditThreads = 64;
  // Leases of spans (docs/farm.md, "Lease rules"): a worker that reads spans gets its tiles in
  // leases of up to max_span_tiles consecutive tiles of a frame, as many as it renders in about
  // `span_seconds` at the rate it has shown (one tile until it has shown one), and never more
  // than its factoring share of what is queued over its threads, so spans shrink toward single
  // tiles as the queue runs out. The tile stays the unit of results, credit and factoring.
  // max_span_tiles 1: every lease one tile.
  int max_span_tiles = Lease::kMaxTiles;
  double span_seconds = 0.1;
  // A worker holding leases that returns no result for this long (or for 8x the slowest tile
  // accepted so far, if longer) loses them: they are requeued and its credit starts again. Heartbeats
  // alone do not keep work a session does not do. Five minutes: longer than any tile of the
  // showcase takes by four orders of magnitude; a farm whose single tiles take longer raises it.
  std::chrono::milliseconds stall_timeout{300000};
  // Faults (bad results, render failures) after which a worker gets no more tiles of a job.
  int max_faults = 3;
  // Tiles held in memory: of one job, and of every job together. A frame's tile table is built
  // when its first tile is handed out and freed when a client acknowledges the frame (or the job
  // ends before the frame is final); a job whose next frame would take the tiles held over either
  // limit waits (JobSnapshot::waiting_for_memory) until frames are acknowledged. 0: no limit.
  int64_t max_job_tiles = 0;
  int64_t max_resident_tiles = 0;
};

class Scheduler {
 public:
  using NowFn = std::function<TimePoint()>;
  using IdFn = std::function<JobId()>;

  // `now` is the clock (tests inject a fake one); `make_id` names jobs (default: random hex).
  explicit Scheduler(SchedulerOptions options = {}, NowFn now = Clock::now, IdFn make_id = {});

  void set_listener(SchedulerListener* listener) { listener_ = listener; }
  void set_pass_planner(PassPlanner planner) { planner_ = std::move(planner); }
  const SchedulerOptions& options() const { return options_; }

  // --- jobs -------------------------------------------------------------------------------
  JobId submit(const JobSpec& spec);
  enum class CancelResult { kCancelled, kAlreadyEnded, kUnknownJob };
  CancelResult cancel(const JobId& id);
  // A client has every tile of the frame: release them. Only finished frames can be acked.
  enum class AckResult { kAcknowledged, kNotFinished, kUnknownFrame, kUnknownJob };
  AckResult acknowledge_frame(const JobId& id, int frame);
  // Moves a live job in the dispatch order (higher first); its queued tiles go out in the new
  // order from the next dispatch, leases in flight are untouched. Ended jobs keep theirs.
  enum class PriorityResult { kChanged, kAlreadyEnded, kUnknownJob };
  PriorityResult set_priority(const JobId& id, int priority);

  // --- workers ----------------------------------------------------------------------------
  WorkerId add_worker(const WorkerInfo& info);
  // Drops the worker; its leases go back to the queue, ended as `why`. No-op for an unknown id.
  void remove_worker(WorkerId id, std::string_view reason, LeaseEnd why = LeaseEnd::kWorkerLeft);
  // Any sign of life: renews the worker's leases.
  void heartbeat(WorkerId id);
  // Pull: the worker can take `count` more tiles (span leases count their tiles). Assignments
  // come from dispatch().
  void request_tiles(WorkerId id, int count);
  // Hands out tiles to every worker with a standing request, one tile per worker per round so
  // that a worker asking for many cannot starve the others of the last tiles. Returns at once
  // (without looking at any worker) when nothing is dispatchable: it runs on every worker message.
  std::vector<Assignment> dispatch();
  // Is there anything dispatch() could hand out: a queued tile of a job that is not held, or
  // (with speculation) a tile of such a job with a single copy in flight?
  bool dispatchable() const;
  // Flow control: a held job gets no new leases, not even speculative copies; its leases in
  // flight run on and their results are accepted. The coordinator holds a job while one of its
  // watch streams is far behind (CoordinatorOptions::watch_backlog_tiles) so finished tiles
  // cannot pile up in memory faster than the client takes them. Returns false for an unknown job.
  bool hold(const JobId& id, bool held);
  bool held(const JobId& id) const;
  enum class ResultOutcome {
    kAccepted,
    kDuplicate,     // another copy of the tile already finished (first copy wins)
    kStaleLease,    // the lease was revoked, expired, or is not this worker's
  };
  // The result for tile `tile` of the lease (a tile the lease covers: the caller checks that).
  ResultOutcome complete(WorkerId worker, LeaseId lease, int tile, TileOutput output);
  // The worker gives leases back unrendered (shutdown): their pending tiles are requeued at the front.
  void return_leases(WorkerId worker, const std::vector<LeaseId>& leases);
  // ... or single tiles of its span leases (the rest of each span stays its own).
  void return_tiles(WorkerId worker, const std::vector<std::pair<LeaseId, int>>& tiles);
  // A bad result or a render failure from `worker` for a tile of job `job`. Ends `lease` (requeued)
  // when it is the worker's live lease; counts a fault against (job, worker name); at
  // max_faults the worker is blocklisted for the job (its other leases of the job are revoked),
  // and when every connected worker is blocklisted the job fails. Returns the fault count (0 for
  // an unknown job).
  int fault(WorkerId worker, const JobId& job, std::optional<LeaseId> lease, const std::string& reason);
  // A refused result no job can be blamed for (it names a job that does not exist): counted in
  // the worker's WorkerStats::refused, as fault() counts the others.
  void count_refused(WorkerId worker);
  // Drops workers silent for longer than the lease timeout, requeueing their leases (a lease has
  // no deadline of its own: it expires with its worker's silence), and revokes stalled workers'.
  // Returns the workers dropped (the coordinator ends their streams).
  std::vector<WorkerId> expire();

  // --- persistence ------------------------------------------------------------------------
  // Rebuilds a job read back from storage: its done tiles stay done (with their payload when the
  // frame is not yet acknowledged), every other tile is queued. Emits no events.
  void restore(JobRecord record);
  // Lease ids keep growing across restarts, so a result for a pre-restart lease is never
  // mistaken for a live one.
  void set_next_lease(LeaseId next) { next_lease_ = std::max(next_lease_, next); }
  LeaseId next_lease() const { return next_lease_; }
  // Drops an ended job (no leases) from memory; false if unknown or still live.
  bool forget(const JobId& id);
  // Is every frame of the job acknowledged by a client?
  bool all_acknowledged(const JobId& id) const;

  // --- queries ----------------------------------------------------------------------------
  std::optional<JobSnapshot> job(const JobId& id) const;
  // What the job is and where it stands, without the per-frame counts job() gathers (those visit
  // every tile: too slow for per-frame events of a long animation). Null for an unknown job.
  const JobHeader* header(const JobId& id) const;
  int tiles_per_frame(const JobId& id) const;  // 0 for an unknown job
  // Tiles of the frames held in memory, of every job (started and not yet acknowledged,
  // released or forgotten): what the scheduler's memory grows with.
  int64_t tiles_held() const { return tiles_held_; }
  std::vector<JobSnapshot> jobs() const;  // in submit order
  // Tiles the worker may still take now: what it has earned (SchedulerOptions::
  // initial_leases_per_thread) less what it holds. INT_MAX when unbounded; 0 for an unknown id.
  int lease_credit(WorkerId id) const;
  // The workers dispatch() looks at: those that want tiles and have credit left, in id order.
  std::vector<WorkerId> wanting_workers() const { return {wanting_.begin(), wanting_.end()}; }
  std::vector<WorkerStats> workers() const;
  std::optional<WorkerStats> worker(WorkerId id) const;
  std::optional<Lease> lease(LeaseId id) const;
  // Every final, unacknowledged tile of the job, by frame then tile (for a client attaching): see
  // deliverable(), the one rule for what may reach a client.
  std::vector<std::pair<TileKey, TileOutput>> finished_tiles(const JobId& id) const;
  // The same, of one frame (absolute number).
  std::vector<std::pair<TileKey, TileOutput>> finished_tiles(const JobId& id, int frame) const;
  // Has every tile of the frame its final result?
  bool frame_final(const JobId& id, int frame) const;
  std::optional<TileRect> tile_rect(const JobId& id, int frame, int tile) const;
  size_t queued_tiles() const;

 private:
  enum class TileState { kQueued, kLeased, kDone };
  struct Tile {
    TileState state = TileState::kQueued;
    std::vector<LeaseId> leases;  // active leases it is pending in (at most 2: the original and a speculative copy)
    TileOutput output;            // when done and not yet acknowledged
    std::string plan;             // passes jobs: the plan of its current pass
    WorkerId finished_by = 0;     // passes jobs: who rendered the output (reported at the frame's end)
  };
  struct Frame {
    // Laid out when the frame's first tile is handed out (or a stored tile of it is restored);
    // freed when a client acknowledges the frame or the job ends before it is final. Empty, the
    // frame costs the few bytes of this struct whatever its size (SchedulerOptions::max_job_tiles).
    std::vector<Tile> tiles;
    int done = 0;
    int passes = 0;               // passes jobs: passes ended
    bool final = false;           // every tile done, at its last pass: the frame may be delivered
    bool acknowledged = false;
    bool released = false;        // the job ended before the frame was final: its tiles are freed
  };
  struct Job : JobHeader {
    TileGrid grid;  // how each frame is cut into tiles
    std::vector<Frame> frames;
    // Tiles waiting for a worker: those given back (a returned or expired lease, a frame's next
    // pass) first, then every tile from the cursor (next_frame, next_tile) on, in frame and tile
    // order, that was never handed out: a range, not a list, so a job of many frames costs no
    // memory per tile until its frames start. `fresh` counts the tiles left in that range.
    std::deque<std::pair<int, int>> requeued;  // (frame index, tile)
    int next_frame = 0, next_tile = 0;
    int64_t fresh = 0;
    int64_t tiles_done = 0;
    uint64_t rays = 0;
    double tile_seconds = 0;  // render time of the done tiles (JobSnapshot::tile_seconds)
    std::map<std::string, int> faults;   // worker name -> faults for this job
    std::set<std::string> blocklisted;   // worker names that get no more tiles of this job
    bool held = false;                   // see hold()
    // Active leases with a pending tile that has no other copy in flight, oldest first: the
    // candidates for a speculative copy. Kept up to date through copies_changed() so speculation
    // never scans leases_.
    std::set<LeaseId> single_copies;
    int64_t tiles_resident = 0;  // tiles of its laid-out frames (what tiles_held() counts)
  };
  struct Worker {
    WorkerStats stats;
    std::set<LeaseId> leases;
    int64_t tiles_held = 0;   // pending tiles of its leases: what credit and factoring count
    int64_t results = 0;      // results returned (accepted, duplicate, or faults up to the blocklist): its credit
    int64_t credit_base = 0;  // `results` when its credit last started again (a stall)
    TimePoint last_progress;  // its last result, or when it last went from no lease to one
  };
  // Runnable jobs in dispatch order: (-priority, submit sequence, id).
  using QueueKey = std::tuple<int, uint64_t, JobId>;

  Job* find_job(const JobId& id);
  const Job* find_job(const JobId& id) const;
  static QueueKey queue_key(const Job& j) { return {-j.spec.priority, j.seq, j.id}; }
  // Cuts the job's frames into tiles by its spec (tile size at least 1): its grid and an empty
  // tile table, frames x tiles per frame, as submit() and restore() start from.
  static void lay_out_tiles(Job& job);
  // Files the job in runnable_ when it has a tile to hand out now, and in waiting_for_memory_
  // when only a frame it cannot start under the memory limits is left.
  void update_runnable(Job& job);
  // Moves the cursor past tiles it must not hand out: of frames already final or released, and
  // tiles of a laid-out frame that are not queued (restored done tiles).
  void settle_cursor(Job& job);
  // Can the frame at the cursor be laid out under the memory limits (true when it already is)?
  bool fits(const Job& job) const;
  // The next tiles to hand out, up to `max` consecutive queued tiles of one frame (frame index,
  // first tile, count), or nullopt (nothing queued, or the next frame does not fit in memory).
  // Tiles given back come first (a run of them that is consecutive in one frame), then the cursor's.
  struct Span {
    int frame = 0, tile = 0, count = 1;
  };
  std::optional<Span> take_span(Job& job, int max);
  bool has_queued(const Job& job) const { return !job.requeued.empty() || job.fresh > 0; }
  void lay_out_frame(Job& job, Frame& frame);
  // Frees a frame's tile table. The caller calls memory_freed() once it has dropped what it drops.
  void drop_frame_tiles(Job& job, Frame& frame);
  // Looks again at the jobs waiting for memory.
  void memory_freed();
  // Nothing of the job is queued any more (cancelled, failed, or ended unfinished).
  void clear_queue(Job& job);
  std::optional<Assignment> next_for(Worker& w, int span);
  // The tiles the worker's next lease should cover (see SchedulerOptions::max_span_tiles), given
  // factoring's share a thread and the queue's length, as dispatch() computed them.
  int span_for(const Worker& w, int64_t share, int64_t queued) const;
  bool blocked(const Job& job, const Worker& w) const { return job.blocklisted.count(w.stats.info.name) > 0; }
  int credit(const Worker& w) const;
  static int credit_threads(const Worker& w) { return std::clamp(w.stats.info.threads, 1, SchedulerOptions::kMaxCreditThreads); }
  // Keeps wanting_ exact: a worker is in it while it wants tiles and holds fewer leases than its
  // credit, so that dispatch, which runs on every worker message, looks only at workers it can
  // serve (a farm of workers at their credit would otherwise cost a scan of all of them each time).
  // Called wherever a worker's wanted count, leases or credit change.
  void update_wanting(Worker& w);
  // The one rule for what may reach a client: a done tile, and of a passes job only once its frame
  // is final (between passes a done tile is an intermediate result).
  static bool deliverable(const Job& job, const Frame& frame, const Tile& tile) {
    return tile.state == TileState::kDone && (!job.spec.passes || frame.final);
  }
  // The frame (absolute number) of the job, or null when the job has no such frame.
  static const Frame* find_frame(const Job& job, int frame);
  // Appends the frame's deliverable tiles, unless the frame is acknowledged.
  static void append_finished(const JobId& id, const Job& job, int frame,
                              std::vector<std::pair<TileKey, TileOutput>>& out);
  // A job that ended without being done frees the tile tables of its frames that are not final:
  // nothing will render or deliver them, and they must not count against the resident limit.
  void release_unfinished(Job& job);
  // Workers that hold leases and returned nothing for longer than the stall limit lose them.
  void revoke_stalled(TimePoint now);
  void fail_job(Job& job, const std::string& error);
  std::optional<Assignment> speculate_for(Worker& w);
  // Adds or removes `lease` in job.single_copies (and the job in speculable_).
  void set_single_copy(Job& job, LeaseId lease, bool single);
  // Runs `change` (which may change the tile's state and its list of leases) and keeps the
  // leases' Lease::single_tiles, and job.single_copies, exact.
  template <typename F>
  void copies_changed(Job& job, Tile& tile, F&& change);
  void count_single(Job& job, LeaseId lease, int delta);
  Assignment issue(Worker& w, Job& job, const Span& span, bool speculative);
  // Takes tile `t` out of the lease (it no longer awaits the tile's result from it): requeued at
  // the front when `requeue`, the job is live and no other copy of it is active. Does not end the
  // lease when it was its last pending tile: the caller does.
  void drop_pending(Lease& lease, int t, bool requeue);
  // Ends a lease; requeues its pending tiles (at the front, in order) when `requeue` and no
  // other copy of them is active.
  void end_lease(LeaseId id, LeaseEnd why, bool requeue);
  void set_state(Job& job, JobState s);
  // A passes job's frame whose every tile is done: plans the next pass (requeues its tiles) or
  // reports the frame's tiles and the frame finished.
  void end_pass(Job& job, int frame_index);
  JobSnapshot snapshot(const Job& job) const;

  SchedulerOptions options_;
  NowFn now_;
  IdFn make_id_;
  SchedulerListener* listener_ = nullptr;
  PassPlanner planner_;
  SchedulerListener null_listener_;
  SchedulerListener& events() { return listener_ ? *listener_ : null_listener_; }

  std::map<JobId, Job> jobs_;
  std::vector<JobId> job_order_;      // submit order
  std::set<QueueKey> runnable_;       // jobs with queued tiles
  std::set<JobId> speculable_;        // jobs with a non-empty single_copies
  std::set<JobId> waiting_for_memory_;  // live jobs whose next frame does not fit (JobSnapshot::waiting_for_memory)
  std::map<WorkerId, Worker> workers_;
  int64_t threads_total_ = 0;         // threads of every connected worker (each clamped as credit() does)
  std::set<WorkerId> wanting_;        // workers with a standing request and credit left: dispatch() looks only here
  std::map<LeaseId, Lease> leases_;   // ids grow with time: begin() is the oldest lease
  uint64_t next_seq_ = 1;
  int64_t tiles_held_ = 0;            // tiles of every job in jobs_ (Job::tiles_resident summed)
  double slowest_tile_ = 0;           // the longest render time of an accepted tile (stall limit)
  WorkerId next_worker_ = 1;
  LeaseId next_lease_ = 1;
};

}  // namespace tessera::server
