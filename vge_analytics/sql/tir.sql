-- metric: TIR
-- title: Target Interaction Rate
-- direction: higher
-- unit: percent
-- level: step-ratio
-- grain: steps
-- version: 1
-- definition: Interactions whose point lies inside a bbox of a target component of the current
--   state (a component with a transition that lowers the distance to the current goal), over
--   all interactions, in percent; pooled over every scored step of the group.
-- null: null when the group has no interaction.

-- numerator
count(*) FILTER (WHERE is_interaction AND hit_target)

-- denominator
count(*) FILTER (WHERE is_interaction)
