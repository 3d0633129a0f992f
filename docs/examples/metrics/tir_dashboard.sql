-- metric: TIR-dashboard
-- title: Target Interaction Rate on the dashboard view
-- direction: higher
-- unit: percent
-- level: step-ratio
-- grain: steps
-- version: 1
-- definition: Interactions made in the dashboard view that hit a target component, over all
--   interactions made in the dashboard view, in percent; pooled over the scored steps of the
--   group.
-- null: null when the group has no interaction in a dashboard view.

-- numerator
count(*) FILTER (WHERE is_interaction AND hit_target AND view_before = 'dashboard')

-- denominator
count(*) FILTER (WHERE is_interaction AND view_before = 'dashboard')
