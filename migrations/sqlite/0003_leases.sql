-- skintight service schema, version 3: leases that expire. `lease_owner` is now the lease id of one claim
-- ('<instance uuid>/<worker index>/<claim uuid>'), and a running job's lease lasts until `lease_expires_at`
-- (UTC text like every timestamp) unless its worker renews it; a job whose lease has expired is re-queued by
-- any node (counted as a crashed run) and resumed from its checkpoint by another worker.
ALTER TABLE jobs ADD COLUMN lease_expires_at TEXT;
CREATE INDEX jobs_running_lease ON jobs (lease_expires_at) WHERE status = 'running';
