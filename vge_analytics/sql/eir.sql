-- metric: EIR
-- title: Effective Interaction Rate
-- direction: higher
-- unit: percent
-- level: step-ratio
-- grain: steps
-- version: 1
-- definition: Interactions whose point lies inside a bbox (in the current view) of any
--   component of the device, over all interactions, in percent; pooled over every scored step
--   of the group. An interaction (PROTOCOL §5) is a parsed Press/Rotate/Push/Pull/Grasp with a
--   coordinate in an interactable view, not aborted by a passive unlock; out-of-range
--   coordinates count as misses.
-- null: null when the group has no interaction.

-- numerator
count(*) FILTER (WHERE is_interaction AND hit_component)

-- denominator
count(*) FILTER (WHERE is_interaction)
