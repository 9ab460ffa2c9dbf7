-- A key's pending deliveries, counted at every job event (the per-key queue cap) and every
-- claim (the per-key cap on deliveries in flight).
CREATE INDEX webhook_deliveries_by_owner ON webhook_deliveries (owner, status);
