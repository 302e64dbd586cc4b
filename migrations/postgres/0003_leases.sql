-- skintight service schema, version 3 (PostgreSQL): leases that expire (see migrations/sqlite/0003_leases.sql).
ALTER TABLE jobs ADD COLUMN lease_expires_at TEXT;
CREATE INDEX jobs_running_lease ON jobs (lease_expires_at) WHERE status = 'running';

-- The time `secs` seconds from now, as stored (lease expiries).
CREATE FUNCTION skintight_later(secs double precision) RETURNS text LANGUAGE sql STABLE AS
$$ SELECT to_char((now() + make_interval(secs => secs)) AT TIME ZONE 'UTC', 'YYYY-MM-DD"T"HH24:MI:SS.MS"Z"') $$;
