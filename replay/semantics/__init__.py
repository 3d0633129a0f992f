"""The rules, as a readable reference: records, action grammar, machine, pure step, planner, classification, episode replay."""
