"""Integration in time: the planted-truth quadrotor (:mod:`.simulator`) and the shipped sample
logs it writes (:mod:`.sample_logs`), the open-loop state integration (:mod:`.openloop`) and
multi-step rollouts of identified models on logged flights (:mod:`.rollout`)."""
