-- skintight service schema, version 1. Timestamps are UTC text 'YYYY-MM-DDTHH:MM:SS.sssZ'.

-- Uploaded meshes, content-addressed per tenant (the same bytes uploaded twice by one tenant are one asset).
CREATE TABLE assets (
    id          TEXT PRIMARY KEY,
    tenant      TEXT NOT NULL,
    sha256      TEXT NOT NULL,
    bytes       INTEGER NOT NULL,
    format      TEXT NOT NULL,
    data        BLOB NOT NULL,
    created_at  TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ', 'now')),
    UNIQUE (tenant, sha256)
);

-- Jobs. `seq` orders them (newest first = highest seq) and is the pagination cursor; `id` is public.
CREATE TABLE jobs (
    seq               INTEGER PRIMARY KEY AUTOINCREMENT,
    id                TEXT NOT NULL UNIQUE,
    tenant            TEXT NOT NULL,
    kind              TEXT NOT NULL,
    spec              TEXT NOT NULL,
    idempotency_key   TEXT,
    request_hash      TEXT NOT NULL,
    status            TEXT NOT NULL CHECK (status IN ('queued', 'running', 'completed', 'failed', 'cancelled')),
    cancel_requested  INTEGER NOT NULL DEFAULT 0,
    -- The worker holding the job while it runs ('<instance uuid>/<worker index>'); NULL otherwise.
    lease_owner       TEXT,
    attempts          INTEGER NOT NULL DEFAULT 0,
    -- Highest iteration announced as an event; iterations re-run after a restart are not announced again.
    iterations        INTEGER NOT NULL DEFAULT 0,
    progress          REAL,
    last_metrics      TEXT,
    checkpoint        BLOB,
    checkpoint_iteration INTEGER,
    summary           TEXT,
    error_code        TEXT,
    error_message     TEXT,
    created_at        TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ', 'now')),
    started_at        TEXT,
    finished_at       TEXT
);
CREATE UNIQUE INDEX jobs_idempotency ON jobs (tenant, idempotency_key) WHERE idempotency_key IS NOT NULL;
CREATE INDEX jobs_tenant_seq ON jobs (tenant, seq);
CREATE INDEX jobs_status_seq ON jobs (status, seq);

-- Every server-sent event of a job is a row; `seq` (1, 2, 3, … per job) is the SSE `id:`.
CREATE TABLE job_events (
    job_id      TEXT NOT NULL REFERENCES jobs (id),
    seq         INTEGER NOT NULL,
    kind        TEXT NOT NULL,
    data        TEXT NOT NULL,
    created_at  TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ', 'now')),
    PRIMARY KEY (job_id, seq)
) WITHOUT ROWID;

-- Named outputs of completed jobs, stored as BLOBs in the database.
CREATE TABLE artifacts (
    job_id        TEXT NOT NULL REFERENCES jobs (id),
    name          TEXT NOT NULL,
    content_type  TEXT NOT NULL,
    bytes         INTEGER NOT NULL,
    sha256        TEXT NOT NULL,
    data          BLOB NOT NULL,
    PRIMARY KEY (job_id, name)
) WITHOUT ROWID;
