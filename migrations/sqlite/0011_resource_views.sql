-- What a resource's GET answers besides its record, computed once at upload: a tool
-- library's tools by T number and its capped import report, as the JSON members the GET
-- adds, so that a GET never parses the stored file (a 60 MB library took ~3 GB a read).
-- Libraries stored before this have none until their first GET writes it.
CREATE TABLE resource_views (
    resource_id TEXT NOT NULL PRIMARY KEY REFERENCES resources (id) ON DELETE CASCADE,
    members     TEXT NOT NULL              -- a JSON object: {"format": .., "tools": .., "report": ..}
);
