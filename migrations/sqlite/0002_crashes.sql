-- skintight service schema, version 2: runs of a job that ended without the server finishing them (the
-- process died during the run), counted at the next start; a job reaching `jobs.max_attempts` of them fails
-- with code `crashed_repeatedly` instead of running again.
ALTER TABLE jobs ADD COLUMN crashes INTEGER NOT NULL DEFAULT 0;
