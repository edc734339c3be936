"""The plan: the typed plan and its file ``plan.yaml``, the work budget and the stage runner (:mod:`planner.plan.pipeline`)."""
