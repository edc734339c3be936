"""The verification stage: windows, the proved window set, and whether the plan decodes everywhere."""
