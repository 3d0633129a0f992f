-- metric: State-F1
-- title: State F1
-- direction: higher
-- unit: percent
-- level: episode-mean
-- grain: episodes
-- version: 1
-- definition: Mean over episodes of the F1 score between the set of visited states and the set
--   of states of the optimal path (the initial state is in both), in percent:
--   F1 = 2 |V & O| / (|V| + |O|). Computed from the visited_states and optimal_states lists,
--   which the replay writes without repeats (first-visit order), so their lengths are the
--   set sizes and |V & O| is the number of visited states found in the optimal list.
-- null: null when the group has no episode.

-- numerator
fsum(
    2.0 * len(list_filter(visited_states, lambda s: list_contains(optimal_states, s)))
    / (len(visited_states) + len(optimal_states))
)

-- denominator
count(*)
