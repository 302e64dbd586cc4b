-- skintight service schema, version 2 (PostgreSQL): runs of a job that ended without a worker finishing
-- them, counted when the job is re-queued; a job reaching `jobs.max_attempts` of them fails with code
-- `crashed_repeatedly` instead of running again.
ALTER TABLE jobs ADD COLUMN crashes BIGINT NOT NULL DEFAULT 0;
