// SPDX-License-Identifier: Apache-2.0
#include "delivery_leases.h"

#include <algorithm>
#include <utility>

namespace tessera::server {

void DeliveryLeases::add(const JobId& job, Deliverer d) {
  auto& list = jobs_[job].deliverers;
  if (std::find(list.begin(), list.end(), d) == list.end()) list.push_back(d);
}

bool DeliveryLeases::delivers(const JobId& job, Deliverer d) const {
  auto it = jobs_.find(job);
  return it != jobs_.end() &&
         std::find(it->second.deliverers.begin(), it->second.deliverers.end(), d) != it->second.deliverers.end();
}

bool DeliveryLeases::has_deliverers(const JobId& job) const {
  auto it = jobs_.find(job);
  return it != jobs_.end() && !it->second.deliverers.empty();
}

std::vector<int> DeliveryLeases::remove(const JobId& job, Deliverer d) {
  std::vector<int> freed;
  auto it = jobs_.find(job);
  if (it == jobs_.end()) return freed;
  std::erase(it->second.deliverers, d);
  it->second.last_given.erase(d);
  auto& frames = it->second.frames;
  for (auto f = frames.begin(); f != frames.end();) {
    if (f->second.holder == d) {
      freed.push_back(f->first);
      f = frames.erase(f);
    } else {
      ++f;
    }
  }
  if (it->second.deliverers.empty() && frames.empty()) jobs_.erase(it);
  return freed;
}

DeliveryLeases::Deliverer DeliveryLeases::holder(const JobId& job, int frame) const {
  auto it = jobs_.find(job);
  if (it == jobs_.end()) return nullptr;
  auto f = it->second.frames.find(frame);
  return f == it->second.frames.end() ? nullptr : f->second.holder;
}

DeliveryLeases::Deliverer DeliveryLeases::least_loaded(const Job& job, Deliverer except) const {
  // A handful of deliverers and the frames they hold at once: counting is cheaper than an index.
  Deliverer best = nullptr;
  std::pair<size_t, uint64_t> best_key{0, 0};  // (frames held, when last given one)
  for (Deliverer d : job.deliverers) {
    if (d == except) continue;
    const size_t n = size_t(
        std::count_if(job.frames.begin(), job.frames.end(), [&](const auto& f) { return f.second.holder == d; }));
    const auto given = job.last_given.find(d);
    const std::pair<size_t, uint64_t> key{n, given == job.last_given.end() ? 0 : given->second};
    if (!best || key < best_key) {
      best = d;
      best_key = key;
    }
  }
  return best;
}

DeliveryLeases::Deliverer DeliveryLeases::assign(const JobId& job, int frame, Deliverer except) {
  auto it = jobs_.find(job);
  if (it == jobs_.end()) return nullptr;
  if (auto f = it->second.frames.find(frame); f != it->second.frames.end()) return f->second.holder;
  Deliverer d = least_loaded(it->second, except);
  if (d) {
    it->second.frames[frame] = Held{d, std::nullopt};
    it->second.last_given[d] = ++it->second.given;
  }
  return d;
}

void DeliveryLeases::sent_whole(const JobId& job, int frame, TimePoint now) {
  auto it = jobs_.find(job);
  if (it == jobs_.end()) return;
  if (auto f = it->second.frames.find(frame); f != it->second.frames.end()) f->second.sent = now;
}

void DeliveryLeases::acknowledged(const JobId& job, int frame) {
  auto it = jobs_.find(job);
  if (it == jobs_.end()) return;
  it->second.frames.erase(frame);
  if (it->second.deliverers.empty() && it->second.frames.empty()) jobs_.erase(it);
}

std::vector<DeliveryLeases::Moved> DeliveryLeases::expire(TimePoint now) {
  std::vector<Moved> out;
  for (auto& [id, job] : jobs_) {
    for (auto& [frame, held] : job.frames) {
      if (!held.sent || now - *held.sent < lease_) continue;
      Moved m{id, frame, held.holder, least_loaded(job, held.holder)};
      if (m.to) {
        held = Held{m.to, std::nullopt};
        job.last_given[m.to] = ++job.given;
      } else {
        held.sent = now;
      }
      out.push_back(m);
    }
  }
  return out;
}

void DeliveryLeases::forget(const JobId& job) { jobs_.erase(job); }

}  // namespace tessera::server
